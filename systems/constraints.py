"""Holonomic constraints f(q, t) = 0 with Lagrange multipliers.

A scene may keep more coordinates than it has degrees of freedom and tie them together
by equations (``[constraints] holonomic = ["x**2 + y**2 - l**2"]``). The equations of
motion then carry one multiplier per constraint,

    M(q, t) qddot + Phi_q^T lambda = F(q, qdot, t),
    Phi_q qddot = gamma(q, qdot, t),

where ``Phi(q, t) = 0`` are the k constraints, ``Phi_q`` their Jacobian (k, n) and
``gamma = -(d(Phi_q qdot)/dq) qdot - 2 Phi_qt qdot - Phi_tt`` minus the part of the second
time derivative of Phi that does not contain qddot. The force of the constraints on the
coordinates is ``-Phi_q^T lambda``. For a pendulum in Cartesian x, y with
``Phi = x**2 + y**2 - l**2`` it is ``-2 lambda (x, y)``: the string's tension is
``2 lambda l``.

The derivation itself (``systems.mechanics``) stays that of the free coordinates: M, F,
the momenta p = dL/dqdot and H(q, p) are those of the unconstrained Lagrangian, and a
state is still ``(q, p)``. What this module adds:

- the symbolic pieces (``holonomic``: Phi, Phi_q, Phi_t and gamma), the constraints for
  the classification (``declared``), and the degrees of freedom (``degrees_of_freedom``:
  coordinates minus the rank of Phi_q at random states);
- the kernel source for a constrained scene (``kernel_source``): its ``rhs`` is Hamilton's
  equations with the constraint force, ``pdot = dL/dq + Q - Phi_q^T lambda``, lambda from
  the saddle-point system ``[[M, Phi_q^T], [Phi_q, 0]] [qddot; lambda] = [F; gamma]``
  solved at every evaluation, and ``project`` puts a state back onto the constraint
  manifold after every step of the ``constrained`` integrator family;
- numpy counterparts for diagnostics (``Numeric``: multipliers, violation, projection of
  an initial state).

The projection (Hairer, Lubich & Wanner, *Geometric Numerical Integration*, IV.4) moves q
by Newton's iterations on ``Phi(q, t) = 0`` along the correction of least kinetic
metric, ``dq = -M^-1 Phi_q^T (Phi_q M^-1 Phi_q^T)^-1 Phi``, and then the velocities onto
``Phi_q qdot + Phi_t = 0`` the same way; the momenta are then p(q, qdot).
"""

from __future__ import annotations

import copy
import math
import random
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy

from systems.classification import NO_CONSTRAINTS, Constraints
from systems.expressions import as_expr
from systems.mechanics import DerivationError

RANK_TOLERANCE = 1e-9
"""Singular values of Phi_q below this fraction of the largest count as zero."""

PROJECTION_ITERATIONS = 8
"""Newton iterations of the position projection before it is given up."""


@dataclass(frozen=True, eq=False)
class Holonomic:
    """The symbolic pieces of k holonomic constraints on n coordinates.

    Attributes
    ----------
    values : tuple of k sympy.Expr
        Phi(q, t).
    jacobian : sympy.Matrix, shape (k, n)
        Phi_q = dPhi/dq.
    time_derivative : tuple of k sympy.Expr
        Phi_t = dPhi/dt (explicit).
    gamma : tuple of k sympy.Expr
        The right-hand side of ``Phi_q qddot = gamma``, in (q, qdot, t).
    """

    values: tuple[sympy.Expr, ...]
    jacobian: sympy.Matrix
    time_derivative: tuple[sympy.Expr, ...]
    gamma: tuple[sympy.Expr, ...]

    @property
    def k(self) -> int:
        return len(self.values)


def count(scene) -> int:
    """The number of holonomic constraints the scene declares (0 for most scenes)."""
    return len(getattr(scene, "holonomic_constraints", ()))


def constrained(scene) -> bool:
    """True if the scene declares constraints of any kind (``[constraints]``): its
    equations carry multipliers and only the ``constrained`` family integrates it."""
    return any(
        getattr(scene, f"{kind}_constraints", ())
        for kind in ("holonomic", "nonholonomic", "unilateral")
    )


def declared(scene) -> Constraints:
    """The scene's constraints as ``systems.classification.Constraints``."""
    k = count(scene)
    if not k:
        return NO_CONSTRAINTS
    return Constraints(
        holonomic=tuple(scene.expression(f"constraints.holonomic[{i}]") for i in range(k))
    )


def multiplier_names(scene) -> list[str]:
    """The CSV columns of the multipliers: ``lambda_1`` .. ``lambda_k`` (none without
    constraints)."""
    return [f"lambda_{i + 1}" for i in range(count(scene))]


def constrains(scene, coordinate: str) -> bool:
    """True if some constraint of the scene contains ``coordinate``: its force then acts
    on it, so the momentum of a cyclic coordinate is not conserved."""
    symbol = scene.symbols[coordinate]
    return any(symbol in f.free_symbols for f in declared(scene).holonomic)


def holonomic(mechanics) -> Holonomic | None:
    """Phi, Phi_q, Phi_t and gamma of ``mechanics``' scene, or None without constraints.

    Remembered on the mechanics.
    """
    scene = mechanics.scene
    if not count(scene):
        return None
    cache = mechanics._cache
    if "holonomic" not in cache:
        q, qd, t = mechanics.q, mechanics.qdot, mechanics.t
        values = declared(scene).holonomic
        jacobian = sympy.Matrix([[sympy.diff(f, x) for x in q] for f in values])
        time_derivative = tuple(sympy.diff(f, t) for f in values)
        gamma = []
        for i in range(len(values)):
            # c = Phi_q qdot + Phi_t; dc/dt = Phi_q qddot + (dc/dq) qdot + dc/dt
            c = sum((jacobian[i, j] * qd[j] for j in range(len(q))), time_derivative[i])
            rest = sum((sympy.diff(c, x) * v for x, v in zip(q, qd, strict=True)), sympy.diff(c, t))
            gamma.append(as_expr(-rest))
        cache["holonomic"] = Holonomic(tuple(values), jacobian, time_derivative, tuple(gamma))
    return cache["holonomic"]


def degrees_of_freedom(mechanics) -> int:
    """Coordinates minus independent constraints: n - rank(Phi_q).

    The rank is the largest found at a few random states (coordinates, t and parameters
    drawn from [0.3, 1.7]), so a rank that drops only on a special set does not count.
    """
    n = mechanics.n
    pieces = holonomic(mechanics)
    if pieces is None:
        return n
    return n - _rank(mechanics, pieces)


def _rank(mechanics, pieces: Holonomic) -> int:
    symbols = [mechanics.t, *mechanics.q, *mechanics.params.values()]
    f = sympy.lambdify(symbols, [as_expr(e) for e in pieces.jacobian], modules="math")
    rng = random.Random(4321)
    best = 0
    for _ in range(5):
        try:
            values = np.array(f(*(rng.uniform(0.3, 1.7) for _ in symbols)), dtype=float)
        except (ValueError, ZeroDivisionError, OverflowError):
            continue
        if not np.all(np.isfinite(values)):
            continue
        s = np.linalg.svd(values.reshape(pieces.k, mechanics.n), compute_uv=False)
        if s.size and s[0] > 0:
            best = max(best, int(np.sum(s > RANK_TOLERANCE * s[0])))
    return best


def check(mechanics) -> None:
    """Refuse constraints this slice cannot integrate, naming the field and why.

    Raises
    ------
    DerivationError
        For dependent constraints or as many independent ones as coordinates, a system
        without a Lagrangian mass matrix, a mass matrix that depends on the velocities
        (L not quadratic in them), or a large system in matrix form.
    """
    scene = mechanics.scene
    for kind in ("nonholonomic", "unilateral"):
        if getattr(scene, f"{kind}_constraints", ()):
            raise DerivationError(
                f"{kind} constraints are not supported yet; only holonomic constraints "
                "f(q, t) = 0 can be integrated for now",
                source=scene.source,
                field=f"constraints.{kind}",
            )
    pieces = holonomic(mechanics)
    if pieces is None:
        return
    n, k = mechanics.n, pieces.k

    def fail(reason: str, field: str = "constraints.holonomic") -> DerivationError:
        return DerivationError(reason, source=scene.source, field=field)

    rank = _rank(mechanics, pieces)
    if rank < k:
        raise fail(
            f"the {k} constraints are not independent (the rank of their Jacobian dPhi/dq "
            f"is {rank}): leave out the ones that follow from the others"
        )
    if k >= n:
        raise fail(
            f"{k} independent constraints on {n} coordinates leave no degree of freedom; "
            "there is nothing to move"
        )
    if mechanics.mass_matrix is None:
        raise fail(
            "constraints need the mass matrix d2L/dqdot2, and this Hamiltonian's Legendre "
            "transform does not invert; give the system by T and V or by a Lagrangian"
        )
    if mechanics.matrix_form is not None:
        raise fail(
            "constraints on a system whose mass matrix is solved numerically (more than "
            "four coupled coordinates) are not supported yet"
        )
    if any(as_expr(e).free_symbols & set(mechanics.qdot) for e in mechanics.mass_matrix):
        raise fail(
            "constraints need a Lagrangian quadratic in the velocities (a mass matrix "
            "d2L/dqdot2 that does not depend on them)"
        )


# -- kernel source ------------------------------------------------------------------------


def kernel_source(writer, mechanics) -> str:
    """The system functions of a constrained scene, for ``systems.compiled``.

    ``writer`` is the compiled module's kernel writer (its ``header``, ``body``,
    ``unpack``, ``unpack_state``). Defines, for the state ``y = (q, p)`` (shape (2n,)):

    - ``rhs(t, y, P, out)``: Hamilton's equations with the constraint force;
    - ``multipliers(t, y, P, out)``: lambda, shape (k,);
    - ``constraint_values(t, y, P, out)``: Phi, shape (k,);
    - ``project(t, y, P) -> bool``: y onto Phi = 0 and Phi_q qdot + Phi_t = 0, in place;
      False if Newton's iteration did not converge;
    - helpers ``c_*`` (the free equations, the saddle-point system, the Jacobian with
      Phi_t as column n, M, qdot and p) and ``c_solve`` (dense Gaussian elimination).
    """
    pieces = holonomic(mechanics)
    scene = mechanics.scene
    n, k = mechanics.n, pieces.k
    m = n + k
    state = writer.unpack_state()
    to_velocities = _velocity_lines(writer, mechanics)
    parts = [f"N_CONSTRAINTS = {k}\n", _SOLVE]
    parts.append(_function(writer, "c_free_rhs(t, y, P, out)", state, mechanics.hamilton_equations))
    parts.append(_function(writer, "c_values(t, y, P, out)", state, pieces.values))
    jacobian = [(f"out[{i}, {j}]", pieces.jacobian[i, j]) for i in range(k) for j in range(n)]
    jacobian += [(f"out[{i}, {n}]", pieces.time_derivative[i]) for i in range(k)]
    parts.append(_assign(writer, "c_jacobian(t, y, P, out)", state, jacobian))
    M = mechanics.mass_matrix
    mass = [(f"out[{i}, {j}]", M[i, j]) for i in range(n) for j in range(n)]
    parts.append(_assign(writer, "c_mass(t, y, P, out)", state, mass))
    parts.append(_function(writer, "c_velocities(t, y, P, out)", state, mechanics.velocities))
    unpack = writer.unpack("q", scene.coordinates) + writer.unpack("qdot", scene.velocity_names)
    parts.append(_function(writer, "c_momenta(t, q, qdot, P, out)", unpack, mechanics.momenta))
    saddle = [(f"W[{i}, {j}]", M[i, j]) for i in range(n) for j in range(n)]
    saddle += [(f"W[{i}, {m}]", mechanics.forcing[i]) for i in range(n)]
    saddle += [(f"W[{n + i}, {m}]", pieces.gamma[i]) for i in range(k)]
    saddle += [(f"W[{n + i}, {j}]", pieces.jacobian[i, j]) for i in range(k) for j in range(n)]
    parts.append(_assign(writer, "c_saddle(t, y, P, W)", state, saddle, before=to_velocities))
    parts.append(_KERNELS.format(n=n, k=k, m=m, maxit=PROJECTION_ITERATIONS))
    return "\n\n".join(parts)


def _velocity_lines(writer, mechanics) -> list[str]:
    """Lines that set ``v_<q>_dot`` from the state (q, p), for functions of (q, qdot)."""
    temps, values = writer.body(mechanics.velocities)
    names = mechanics.scene.velocity_names
    return temps + [f"v_{name} = {value}" for name, value in zip(names, values, strict=True)]


def _function(writer, signature: str, unpack: list[str], exprs: Sequence) -> str:
    targets = [f"out[{i}]" for i in range(len(exprs))]
    return _assign(writer, signature, unpack, list(zip(targets, exprs, strict=True)))


def _assign(
    writer, signature: str, unpack: list[str], pairs: list[tuple[str, object]], before=()
) -> str:
    """A function that assigns each expression of ``pairs`` to its target, after the
    lines ``before`` (which may use the parameters)."""
    lines = writer.header(signature, unpack) + list(before)
    temps, values = writer.body([expr for _, expr in pairs])
    lines += temps
    lines += [f"{target} = {value}" for (target, _), value in zip(pairs, values, strict=True)]
    return lines[0] + "\n" + "\n".join("    " + line for line in lines[1:]) + "\n"


_SOLVE = '''\
def c_solve(W, m, r):
    """Solve A X = B in place for W = [A | B] (m, m + r), A square and invertible.

    Gaussian elimination with partial pivoting (the saddle-point matrix is symmetric but
    indefinite, so no Cholesky); on return columns m .. m + r - 1 hold X. A singular A
    gives inf or nan, which the driver rejects like any non-finite step.
    """
    for j in range(m):
        pivot = j
        for i in range(j + 1, m):
            if abs(W[i, j]) > abs(W[pivot, j]):
                pivot = i
        if pivot != j:
            for c in range(j, m + r):
                W[j, c], W[pivot, c] = W[pivot, c], W[j, c]
        for i in range(j + 1, m):
            f = W[i, j] / W[j, j]
            for c in range(j, m + r):
                W[i, c] -= f * W[j, c]
    for c in range(m, m + r):
        for i in range(m - 1, -1, -1):
            s = W[i, c]
            for l in range(i + 1, m):
                s -= W[i, l] * W[l, c]
            W[i, c] = s / W[i, i]
'''

_KERNELS = '''\
def _settled(size, previous, scale):
    """Newton's correction is at round-off: tiny, or small and no longer shrinking
    (quadratic convergence halves the digits left at least; noise does not)."""
    if size <= 1e-14 * scale:
        return True
    return size <= 1e-10 * scale and size > 0.5 * previous


def c_lambda(t, y, P, W):
    """Fill and solve the saddle-point system: W[{n}:{m}, {m}] is lambda, W[:{n}, {m}] qddot."""
    for i in range({k}):
        for j in range({k}):
            W[{n} + i, {n} + j] = 0.0
    c_saddle(t, y, P, W)
    for i in range({n}):
        for j in range({k}):
            W[i, {n} + j] = W[{n} + j, i]
    c_solve(W, {m}, 1)


def rhs(t, y, P, out):
    W = np.empty(({m}, {m} + 1))
    c_lambda(t, y, P, W)
    J = np.empty(({k}, {n} + 1))
    c_jacobian(t, y, P, J)
    c_free_rhs(t, y, P, out)
    for i in range({n}):
        acc = 0.0
        for j in range({k}):
            acc += J[j, i] * W[{n} + j, {m}]
        out[{n} + i] -= acc


def multipliers(t, y, P, out):
    W = np.empty(({m}, {m} + 1))
    c_lambda(t, y, P, W)
    for j in range({k}):
        out[j] = W[{n} + j, {m}]


def constraint_values(t, y, P, out):
    c_values(t, y, P, out)


def c_metric_solve(t, y, P, J, rhs_k, dq):
    """dq = M^-1 J^T (J M^-1 J^T)^-1 rhs_k for J = Phi_q at y (the least-metric step)."""
    B = np.empty(({n}, {n} + {k}))
    Mq = np.empty(({n}, {n}))
    c_mass(t, y, P, Mq)
    for i in range({n}):
        for j in range({n}):
            B[i, j] = Mq[i, j]
        for j in range({k}):
            B[i, {n} + j] = J[j, i]
    c_solve(B, {n}, {k})
    S = np.empty(({k}, {k} + 1))
    for i in range({k}):
        for j in range({k}):
            acc = 0.0
            for l in range({n}):
                acc += J[i, l] * B[l, {n} + j]
            S[i, j] = acc
        S[i, {k}] = rhs_k[i]
    c_solve(S, {k}, 1)
    for i in range({n}):
        acc = 0.0
        for j in range({k}):
            acc += B[i, {n} + j] * S[j, {k}]
        dq[i] = acc


def project(t, y, P):
    """Move y = (q, p) onto Phi(q, t) = 0 and Phi_q qdot + Phi_t = 0, in place."""
    qd = np.empty({n})
    c_velocities(t, y, P, qd)
    phi = np.empty({k})
    J = np.empty(({k}, {n} + 1))
    dq = np.empty({n})
    converged = False
    previous = math.inf
    for it in range({maxit}):
        c_values(t, y, P, phi)
        c_jacobian(t, y, P, J)
        c_metric_solve(t, y, P, J, phi, dq)
        size = 0.0
        scale = 1.0
        for i in range({n}):
            y[i] -= dq[i]
            size = max(size, abs(dq[i]))
            scale = max(scale, abs(y[i]))
        if not size == size:
            return False
        if _settled(size, previous, scale):
            converged = True
            break
        previous = size
    c_jacobian(t, y, P, J)
    r = np.empty({k})
    for i in range({k}):
        acc = J[i, {n}]
        for l in range({n}):
            acc += J[i, l] * qd[l]
        r[i] = acc
    c_metric_solve(t, y, P, J, r, dq)
    for i in range({n}):
        qd[i] -= dq[i]
    p = np.empty({n})
    c_momenta(t, y, qd, P, p)
    for i in range({n}):
        y[{n} + i] = p[i]
    return converged
'''


# -- numpy, for diagnostics and the initial state -----------------------------------------


class Numeric:
    """The constraints of a compiled system evaluated with numpy, many states at once.

    Parameters
    ----------
    compiled : CompiledSystem
        Of a scene with holonomic constraints; its parameter values are used (see
        ``bound_to``).
    """

    def __init__(self, compiled):
        self.compiled = compiled
        mech = compiled.mechanics
        self.n, self.pieces = mech.n, holonomic(mech)
        if self.pieces is None:
            raise ValueError("the scene has no constraints")
        self.k = self.pieces.k
        params = tuple(mech.params[name] for name in compiled.parameter_names)
        t, q, qd = mech.t, mech.q, mech.qdot

        def lam(args, exprs):
            return sympy.lambdify((*args, params), [as_expr(e) for e in exprs], modules="numpy")

        self._phi = lam((t, q), self.pieces.values)
        self._jacobian = lam((t, q), [*self.pieces.jacobian, *self.pieces.time_derivative])
        self._mass = lam((t, q, qd), list(mech.mass_matrix))
        self._forcing = lam((t, q, qd), list(mech.forcing))
        self._gamma = lam((t, q, qd), self.pieces.gamma)
        self._velocities = lam((t, q, mech.p), mech.velocities)
        self._momenta = lam((t, q, qd), mech.momenta)

    def bound_to(self, compiled) -> Numeric:
        """The same functions with ``compiled``'s parameter values (nothing is lambdified
        again: a parameter slider costs nothing here)."""
        other = copy.copy(self)
        other.compiled = compiled
        return other

    def _stack(self, f, shape, N, *args) -> np.ndarray:
        """``f`` (a list of expressions) at N states, as an array (N, *shape)."""
        values = f(*args, self.compiled.parameters)
        return np.stack([np.broadcast_to(np.asarray(v, float), (N,)) for v in values], -1).reshape(
            (N, *shape)
        )

    def _split(self, t, Y):
        Y = np.atleast_2d(np.asarray(Y, dtype=float))
        N = len(Y)
        ts = np.broadcast_to(np.asarray(t, dtype=float), (N,))
        return ts, Y, N

    def values(self, t, Y: np.ndarray) -> np.ndarray:
        """Phi at states Y (N, 2n); returns (N, k)."""
        ts, Y, N = self._split(t, Y)
        return self._stack(self._phi, (self.k,), N, ts, Y[:, : self.n].T)

    def violation(self, t, Y: np.ndarray) -> float:
        """The largest |Phi_i| over the states Y (N, 2n)."""
        return float(np.max(np.abs(self.values(t, Y)))) if len(np.atleast_2d(Y)) else 0.0

    def qdot(self, t, Y: np.ndarray) -> np.ndarray:
        ts, Y, N = self._split(t, Y)
        n = self.n
        return self._stack(self._velocities, (n,), N, ts, Y[:, :n].T, Y[:, n:].T)

    def multipliers(self, t, Y: np.ndarray) -> np.ndarray:
        """lambda at states Y (N, 2n) from the saddle-point system; returns (N, k)."""
        ts, Y, N = self._split(t, Y)
        n, k = self.n, self.k
        Q, Qd = Y[:, :n].T, self.qdot(ts, Y).T
        M = self._stack(self._mass, (n, n), N, ts, Q, Qd)
        F = self._stack(self._forcing, (n,), N, ts, Q, Qd)
        gamma = self._stack(self._gamma, (k,), N, ts, Q, Qd)
        J = self._stack(self._jacobian, ((n + 1) * k,), N, ts, Q)[:, : n * k].reshape(N, k, n)
        A = np.zeros((N, n + k, n + k))
        A[:, :n, :n] = M
        A[:, :n, n:] = np.transpose(J, (0, 2, 1))
        A[:, n:, :n] = J
        b = np.concatenate([F, gamma], axis=1)[..., None]
        try:
            return np.linalg.solve(A, b)[:, n:, 0]
        except np.linalg.LinAlgError:  # some state where Phi_q loses rank: nan there
            out = np.full((N, k), np.nan)
            for row in range(N):
                try:
                    out[row] = np.linalg.solve(A[row], b[row])[n:, 0]
                except np.linalg.LinAlgError:
                    pass
            return out

    def project(self, t: float, y: np.ndarray) -> np.ndarray:
        """One state (2n,) moved onto the constraints (positions, then velocities), as
        the kernels' ``project`` does; for an initial state off the manifold.

        Raises
        ------
        DerivationError
            If Newton's iteration does not converge (no nearby point satisfies Phi = 0).
        """
        n = self.n
        y = np.array(y, dtype=float)
        qd = self.qdot(t, y)[0]
        previous = math.inf
        for _ in range(4 * PROJECTION_ITERATIONS):
            try:
                J, dq = self._metric_step(t, y[:n], qd, self.values(t, y)[0])
            except np.linalg.LinAlgError:  # Phi_q (or M) singular here
                break
            y[:n] -= dq
            if not np.all(np.isfinite(y)):
                break
            size, scale = np.max(np.abs(dq)), max(1.0, np.max(np.abs(y[:n])))
            if size <= 1e-14 * scale or (size <= 1e-10 * scale and size > 0.5 * previous):
                try:
                    J, dq = self._metric_step(t, y[:n], qd, None)
                except np.linalg.LinAlgError:
                    break
                qd = qd - dq
                p = np.asarray(self._momenta(t, y[:n], qd, self.compiled.parameters), float)
                y[n:] = p.reshape(n)
                return y
            previous = size
        raise DerivationError(
            "the initial state cannot be moved onto the constraints (Newton's iteration "
            f"on Phi(q) = 0 did not converge from q = {list(np.round(y[:n], 6))})",
            source=self.compiled.mechanics.scene.source,
            field="initial",
        )

    def _metric_step(self, t, q, qd, residual):
        """(J, M^-1 J^T (J M^-1 J^T)^-1 r) for r = residual, or r = J qdot + Phi_t."""
        n, k = self.n, self.k
        P = self.compiled.parameters
        both = np.asarray(self._jacobian(t, q, P), float).reshape(-1)
        J, Jt = both[: n * k].reshape(k, n), both[n * k :]
        M = np.asarray(self._mass(t, q, qd, P), float).reshape(n, n)
        r = J @ qd + Jt if residual is None else residual
        X = np.linalg.solve(M, J.T)
        return J, X @ np.linalg.solve(J @ X, r)
