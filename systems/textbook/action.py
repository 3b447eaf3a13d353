"""Hamilton's principle: the action along paths, its variations, and the two-point problem.

The action ``S = integral of L(q, qdot, t) dt`` uses the scene's Lagrangian (effects such
as dissipation are not part of it, so for a dissipative scene the true path is not
stationary). Paths are sampled: ``t`` shape (K,), ``q`` and ``qdot`` shape (K, n); the
integral is Simpson's rule on the samples (fourth order on a uniform grid).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize
import sympy

from systems.calculus import Calculus, Unsupported
from systems.mechanics import Mechanics
from systems.textbook._numeric import cache_for, vectorize, with_parameters

Variation = tuple[np.ndarray, np.ndarray]
DENSE_LIMIT = 600  # unknowns beyond which the dense scipy.optimize.root fallback is skipped


@dataclass(frozen=True)
class ActionCurve:
    """S(eps) along the varied paths ``q + eps * eta(t)``.

    Attributes
    ----------
    eps, action : ndarray, shape (E,)
        The sampled amplitudes and the action of each varied path.
    slope : float
        dS/deps at eps = 0 by a symmetric difference: zero on a true path.
    curvature : float
        d2S/deps2 at eps = 0 (the second variation along eta).
    step : float
        The difference step used for ``slope`` and ``curvature``.
    """

    eps: np.ndarray
    action: np.ndarray
    slope: float
    curvature: float
    step: float


@dataclass(frozen=True)
class SecondVariation:
    """The second variation of S over a basis of sine variations.

    Attributes
    ----------
    matrix : ndarray, shape (b, b)
        ``d2 S / d eps_a d eps_b`` at eps = 0 for the basis variations, b = modes * n,
        ordered (mode 1 of every coordinate, mode 2 of every coordinate, ...).
    eigenvalues : ndarray, shape (b,)
        Ascending.
    nature : str
        ``"minimum"`` (all positive), ``"saddle"`` (the path is only stationary: past a
        conjugate point), ``"maximum"``, or ``"degenerate"`` (a zero eigenvalue: at a
        conjugate point).
    """

    matrix: np.ndarray
    eigenvalues: np.ndarray
    nature: str


@dataclass(frozen=True)
class BoundaryPath:
    """A path from configuration A to configuration B in a given time.

    Attributes
    ----------
    t : ndarray, shape (K,)
    q, qdot : ndarray, shape (K, n)
    action : float
        The action along the path.
    converged : bool
    message : str
    method : str
        ``"action"`` (stationary discrete action) or ``"shooting"``.
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    action: float
    converged: bool
    message: str
    method: str


# -- the Lagrangian, numerically ---------------------------------------------------------------


def lagrangian_function(
    mechanics: Mechanics, parameters: Mapping[str, float] | None = None
) -> Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """``L(t (K,), q (K, n), qdot (K, n)) -> (K,)`` with the parameters' values."""
    f = _functions(mechanics, parameters)["L"]
    return lambda t, q, qdot: f(*_columns(t, q, qdot))[0]


def action(
    mechanics: Mechanics,
    t: np.ndarray,
    q: np.ndarray,
    qdot: np.ndarray,
    *,
    parameters: Mapping[str, float] | None = None,
) -> float:
    """The action ``S = integral of L dt`` along a sampled path (Simpson's rule).

    Parameters
    ----------
    t : ndarray, shape (K,)
        Increasing times, K >= 3 (a uniform grid gives fourth-order accuracy).
    q, qdot : ndarray, shape (K, n)
    """
    t, q, qdot = _path(mechanics, t, q, qdot)
    values = lagrangian_function(mechanics, parameters)(t, q, qdot)
    return float(scipy.integrate.simpson(values, x=t))


def sine_variation(
    t: np.ndarray, k: int = 1, direction: Sequence[float] | int = 0, *, n: int | None = None
) -> Variation:
    """The variation ``eta(t) = sin(k pi (t - t1) / (t2 - t1)) * direction`` and its rate.

    Parameters
    ----------
    t : ndarray, shape (K,)
        The path's times; t1 = t[0], t2 = t[-1], where eta vanishes.
    k : int
        The mode number (k - 1 interior nodes).
    direction : int or sequence of n floats
        A coordinate index, or a vector in coordinate space.
    n : int
        Number of coordinates (needed when ``direction`` is an index).

    Returns
    -------
    eta, etadot : ndarray, shape (K, n)
    """
    t = np.asarray(t, dtype=float)
    if np.ndim(direction) == 0:
        if n is None:
            raise ValueError("give n, the number of coordinates, with a coordinate index")
        vector = np.zeros(n)
        vector[int(direction)] = 1.0
    else:
        vector = np.asarray(direction, dtype=float)
    span = t[-1] - t[0]
    phase = k * np.pi * (t - t[0]) / span
    eta = np.sin(phase)[:, None] * vector
    etadot = (k * np.pi / span) * np.cos(phase)[:, None] * vector
    return eta, etadot


def action_curve(
    mechanics: Mechanics,
    t: np.ndarray,
    q: np.ndarray,
    qdot: np.ndarray,
    eps: np.ndarray | None = None,
    *,
    variation: Variation | Callable[[np.ndarray], Variation] | None = None,
    k: int = 1,
    direction: Sequence[float] | int = 0,
    step: float = 1e-3,
    parameters: Mapping[str, float] | None = None,
) -> ActionCurve:
    """S(eps) for the varied paths ``q + eps*eta``, with dS/deps and d2S/deps2 at 0.

    Parameters
    ----------
    t : ndarray, shape (K,)
    q, qdot : ndarray, shape (K, n)
        The path (usually a stretch of the computed trajectory).
    eps : ndarray, shape (E,), optional
        Amplitudes to sample; default 41 values in [-0.5, 0.5].
    variation : (eta, etadot) arrays of shape (K, n), or a function of t returning them
        A user-given variation; it should vanish at t[0] and t[-1]. Default: the sine
        mode ``k`` along ``direction`` (see ``sine_variation``).
    step : float
        The symmetric-difference step for the slope and curvature.
    """
    t, q, qdot = _path(mechanics, t, q, qdot)
    if variation is None:
        eta, etadot = sine_variation(t, k, direction, n=mechanics.n)
    elif callable(variation):
        eta, etadot = variation(t)
    else:
        eta, etadot = variation
    eta = np.asarray(eta, dtype=float).reshape(q.shape)
    etadot = np.asarray(etadot, dtype=float).reshape(q.shape)
    eps = np.linspace(-0.5, 0.5, 41) if eps is None else np.asarray(eps, dtype=float)
    L = lagrangian_function(mechanics, parameters)

    def S(e: float) -> float:
        return float(scipy.integrate.simpson(L(t, q + e * eta, qdot + e * etadot), x=t))

    values = np.array([S(e) for e in eps])
    plus, zero, minus = S(step), S(0.0), S(-step)
    return ActionCurve(
        eps=eps,
        action=values,
        slope=(plus - minus) / (2 * step),
        curvature=(plus - 2 * zero + minus) / step**2,
        step=step,
    )


def second_variation(
    mechanics: Mechanics,
    t: np.ndarray,
    q: np.ndarray,
    qdot: np.ndarray,
    *,
    modes: int = 6,
    parameters: Mapping[str, float] | None = None,
) -> SecondVariation:
    """The second variation of S on the sine modes 1..modes of every coordinate.

    ``d2S[eta] = integral of (etadot.A.etadot + 2 eta.B.etadot + eta.C.eta) dt`` with
    ``A = d2L/dqdot2``, ``B = d2L/dq dqdot``, ``C = d2L/dq2`` along the path, from exact
    derivatives of L (no differences). A negative eigenvalue means the path is not a
    minimum of the action: it is past a conjugate point (for the oscillator, half a period).

    Parameters
    ----------
    t : ndarray, shape (K,)
    q, qdot : ndarray, shape (K, n)
    modes : int
        Sine modes per coordinate; the basis has b = modes * n variations.
    """
    t, q, qdot = _path(mechanics, t, q, qdot)
    n = mechanics.n
    A, B, C = _hessian_blocks(mechanics, parameters, t, q, qdot)  # each (K, n, n)
    basis = [sine_variation(t, k, j, n=n) for k in range(1, modes + 1) for j in range(n)]
    E = np.stack([b[0] for b in basis])  # (b, K, n)
    Ed = np.stack([b[1] for b in basis])
    # optimize: pairwise contractions (b K n^2 + b^2 K n), not one loop over all five
    # indices (b^2 K n^2: a minute for a twenty-link chain)
    integrand = (
        np.einsum("aki,kij,bkj->abk", Ed, A, Ed, optimize=True)
        + np.einsum("aki,kij,bkj->abk", E, B, Ed, optimize=True)
        + np.einsum("bki,kij,akj->abk", E, B, Ed, optimize=True)
        + np.einsum("aki,kij,bkj->abk", E, C, E, optimize=True)
    )
    matrix = scipy.integrate.simpson(integrand, x=t, axis=-1)
    matrix = (matrix + matrix.T) / 2
    eigenvalues = np.linalg.eigvalsh(matrix)
    tol = 1e-9 * float(np.max(np.abs(eigenvalues)))
    if np.any(np.abs(eigenvalues) <= tol):
        nature = "degenerate"
    elif np.all(eigenvalues > 0):
        nature = "minimum"
    elif np.all(eigenvalues < 0):
        nature = "maximum"
    else:
        nature = "saddle"
    return SecondVariation(matrix=matrix, eigenvalues=eigenvalues, nature=nature)


# -- the two-point boundary problem ------------------------------------------------------------


def solve_two_point(
    mechanics: Mechanics,
    qa: Sequence[float],
    qb: Sequence[float],
    duration: float,
    *,
    t0: float = 0.0,
    nodes: int = 201,
    guess: np.ndarray | None = None,
    parameters: Mapping[str, float] | None = None,
) -> BoundaryPath:
    """The path from ``qa`` at t0 to ``qb`` at t0 + duration that makes the action stationary.

    The action is discretized with the midpoint rule,
    ``S_d = sum_k h L((q_k + q_k+1)/2, (q_k+1 - q_k)/h, t_k + h/2)``, and the discrete
    Euler-Lagrange equations ``dS_d/dq_k = 0`` at the interior nodes are solved by
    Newton's method on their exact block-tridiagonal Jacobian (``solve_banded``, linear in
    the number of nodes), falling back to ``scipy.optimize.root`` (hybr, dense) for small
    problems Newton does not settle. Second-order accurate in h. Which of several
    stationary paths is found depends on ``guess`` (default: the straight line from A to B).

    Parameters
    ----------
    qa, qb : sequence of n floats
    nodes : int
        K, the number of time nodes including both ends.
    guess : ndarray, shape (K, n), optional

    Returns
    -------
    BoundaryPath
        ``qdot`` from second-order differences of q; ``action`` is S_d.
    """
    n = mechanics.n
    qa, qb = np.asarray(qa, dtype=float), np.asarray(qb, dtype=float)
    t = t0 + np.linspace(0.0, duration, nodes)
    h = duration / (nodes - 1)
    if guess is None:
        guess = qa + np.outer(np.linspace(0.0, 1.0, nodes), qb - qa)
    guess = np.asarray(guess, dtype=float).reshape(nodes, n)
    functions = _functions(mechanics, parameters)
    t_mid = t[:-1] + h / 2

    def full(x: np.ndarray) -> np.ndarray:
        return np.vstack([qa, x.reshape(nodes - 2, n), qb])

    m = nodes - 2

    def blocks(x: np.ndarray):
        """R (m, n) and the Jacobian's blocks: dR_k/dq_k-1, dR_k/dq_k, dR_k/dq_k+1."""
        q = full(x)
        mid, vel = (q[:-1] + q[1:]) / 2, (q[1:] - q[:-1]) / h
        cols = _columns(t_mid, mid, vel)
        Lq = functions["Lq"](*cols).T  # (K-1, n), one row per segment
        Lv = functions["Lv"](*cols).T
        A, B, C = (
            functions[key](*cols).T.reshape(nodes - 1, n, n) for key in ("Lvv", "Lqv", "Lqq")
        )
        R = (h / 2) * (Lq[:-1] + Lq[1:]) + Lv[:-1] - Lv[1:]  # (K-2, n)
        BT = np.transpose(B, (0, 2, 1))
        # Interior node k + 1 lies between segment k (before it) and segment k + 1 (after).
        lower = ((h / 2) * (C / 2 - B / h) + (BT / 2 - A / h))[:-1]  # via the segment before
        diag = ((h / 2) * (C / 2 + B / h) + (BT / 2 + A / h))[:-1] + (
            (h / 2) * (C / 2 - B / h) - (BT / 2 - A / h)
        )[1:]
        upper = ((h / 2) * (C / 2 + B / h) - (BT / 2 + A / h))[1:]  # via the segment after
        return R, lower, diag, upper

    def residual(x: np.ndarray):
        R, lower, diag, upper = blocks(x)
        J = np.zeros((m, n, m, n))
        for k in range(m):
            J[k, :, k, :] = diag[k]
            if k > 0:
                J[k, :, k - 1, :] = lower[k]
            if k < m - 1:
                J[k, :, k + 1, :] = upper[k]
        return R.ravel(), J.reshape(m * n, m * n)

    x0 = guess[1:-1].ravel()
    with np.errstate(all="ignore"):
        x, success, message = _banded_newton(blocks, x0, n)
        if not success and m * n <= DENSE_LIMIT:
            solution = scipy.optimize.root(
                residual, x0, jac=True, method="hybr", options={"xtol": 1e-13}
            )
            x, success, message = solution.x, bool(solution.success), str(solution.message)
    q = full(x)
    qdot = np.gradient(q, t, axis=0, edge_order=2)
    mid, vel = (q[:-1] + q[1:]) / 2, (q[1:] - q[:-1]) / h
    S = float(h * np.sum(functions["L"](*_columns(t_mid, mid, vel))[0]))
    size = float(np.max(np.abs(blocks(x)[0]))) if nodes > 2 else 0.0
    converged = bool(success) and np.isfinite(size)
    return BoundaryPath(t, q, qdot, S, converged, message, "action")


def shoot_two_point(
    mechanics: Mechanics,
    qa: Sequence[float],
    qb: Sequence[float],
    duration: float,
    *,
    t0: float = 0.0,
    samples: int = 201,
    velocity_guess: Sequence[float] | None = None,
    parameters: Mapping[str, float] | None = None,
    rtol: float = 1e-11,
) -> BoundaryPath:
    """The same two-point problem by shooting: root-find the initial velocity.

    Lagrange's equations of the conservative Lagrangian (``M qddot = F - Q``, the
    effects Q removed) are integrated with ``solve_ivp`` (DOP853), and
    ``scipy.optimize.root`` adjusts qdot(t0) until q(t0 + duration) = qb.

    Returns
    -------
    BoundaryPath
        Sampled at ``samples`` uniform times; ``action`` by Simpson's rule.
    """
    n = mechanics.n
    qa, qb = np.asarray(qa, dtype=float), np.asarray(qb, dtype=float)
    functions = _functions(mechanics, parameters)
    t_end = t0 + duration

    def rhs(time, y):
        cols = [np.asarray(time, dtype=float), *np.asarray(y, dtype=float)]  # one point
        M = functions["M"](*cols).reshape(n, n)
        F = functions["F"](*cols)
        return np.concatenate([y[n:], np.linalg.solve(M, F)])

    def run(v0, dense=False):
        return scipy.integrate.solve_ivp(
            rhs,
            (t0, t_end),
            np.concatenate([qa, v0]),
            method="DOP853",
            rtol=rtol,
            atol=rtol * 1e-1,
            dense_output=dense,
        )

    def miss(v0):
        result = run(v0)
        if result.status != 0:
            return np.full(n, 1e6)
        return result.y[:n, -1] - qb

    v0 = (qb - qa) / duration if velocity_guess is None else np.asarray(velocity_guess, float)
    with np.errstate(all="ignore"):
        solution = scipy.optimize.root(miss, v0, method="hybr", options={"xtol": 1e-13})
    final = run(solution.x, dense=True)
    t = np.linspace(t0, t_end, samples)
    y = final.sol(t).T
    q, qdot = y[:, :n], y[:, n:]
    S = float(scipy.integrate.simpson(functions["L"](*_columns(t, q, qdot))[0], x=t))
    converged = bool(solution.success) and float(np.max(np.abs(q[-1] - qb))) < 1e-8 * (
        1 + float(np.max(np.abs(qb)))
    )
    return BoundaryPath(t, q, qdot, S, converged, str(solution.message), "shooting")


# -- helpers -----------------------------------------------------------------------------------


def _banded_newton(blocks, x0: np.ndarray, n: int, max_iterations: int = 60):
    """Newton's method with backtracking on a block-tridiagonal system (``solve_banded``).

    ``blocks(x)`` returns R (m, n) and the (m, n, n) blocks below, on and above the
    diagonal. Returns (x, converged, message).
    """
    x = np.array(x0, dtype=float)
    R, lower, diag, upper = blocks(x)
    m = R.shape[0]
    size = m * n
    bandwidth = 2 * n - 1
    rows = np.arange(n)[:, None]
    cols = np.arange(n)[None, :]
    norm = float(np.max(np.abs(R))) if size else 0.0
    for _ in range(max_iterations):
        if not np.isfinite(norm):
            return x, False, "the residual is not finite"
        ab = np.zeros((2 * bandwidth + 1, size))
        for offset, block, start in ((0, diag, 0), (-1, lower, 1), (1, upper, 0)):
            k = np.arange(start, m - (1 if offset == 1 else 0))
            if k.size == 0:
                continue
            r = (k[:, None, None] * n + rows)[..., :].repeat(n, axis=2)
            c = ((k + offset)[:, None, None] * n + cols).repeat(n, axis=1)
            ab[bandwidth + r - c, c] = block[k]
        try:
            step = scipy.linalg.solve_banded((bandwidth, bandwidth), ab, R.ravel())
        except (np.linalg.LinAlgError, ValueError):
            return x, False, "singular Jacobian"
        scale = 1.0
        for _ in range(30):
            trial = x - scale * step
            R_trial, *rest = blocks(trial)
            norm_trial = float(np.max(np.abs(R_trial)))
            if (
                np.isfinite(norm_trial)
                and norm_trial < norm * (1 - 1e-4 * scale)
                or (np.isfinite(norm_trial) and norm_trial <= 1e-14)
            ):
                break
            scale /= 2
        else:
            converged = float(np.max(np.abs(step))) <= 1e-12 * (1 + float(np.max(np.abs(x))))
            if converged:
                return x, True, "converged (the residual is at rounding level)"
            return x, False, "no further decrease of the residual"
        x, R, (lower, diag, upper), norm = trial, R_trial, rest, norm_trial
        if float(np.max(np.abs(scale * step))) <= 1e-13 * (1 + float(np.max(np.abs(x)))):
            return x, True, "converged"
    return x, False, "too many Newton iterations"


def _path(mechanics: Mechanics, t, q, qdot):
    t = np.asarray(t, dtype=float)
    n = mechanics.n
    q = np.asarray(q, dtype=float).reshape(len(t), n)
    qdot = np.asarray(qdot, dtype=float).reshape(len(t), n)
    if len(t) < 3:
        raise ValueError("a path needs at least 3 samples")
    if mechanics.lagrangian is None:
        raise ValueError(
            "Hamilton's principle needs a Lagrangian, and this scene's Hamiltonian has none"
        )
    return t, q, qdot


def _columns(t, q, qdot) -> list[np.ndarray]:
    """Arguments in lambdify order: t, q_1..q_n, qdot_1..qdot_n, each shape (K,)."""
    t = np.asarray(t, dtype=float)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    qdot = np.atleast_2d(np.asarray(qdot, dtype=float))
    return [t, *q.T, *qdot.T]


def _functions(mechanics: Mechanics, parameters) -> dict:
    """Lambdified L, its derivatives, M and the conservative F, cached per mechanics."""
    if mechanics.lagrangian is None:
        raise ValueError(
            "Hamilton's principle needs a Lagrangian, and this scene's Hamiltonian has none"
        )
    key = ("action", tuple(sorted((parameters or {}).items())))
    cache = cache_for(mechanics)
    if key in cache:
        return cache[key]
    args = [mechanics.t, *mechanics.q, *mechanics.qdot]
    L = with_parameters(mechanics.lagrangian, mechanics, parameters)
    Lq, Lv, Lvv, Lqv, Lqq = _derivatives(mechanics, L)
    functions = {
        "L": vectorize([L], args),
        "Lq": vectorize(Lq, args),
        "Lv": vectorize(Lv, args),
        "Lvv": vectorize(Lvv, args),
        "Lqv": vectorize(Lqv, args),
        "Lqq": vectorize(Lqq, args),
    }
    if mechanics.mass_matrix is not None:
        M = with_parameters(mechanics.mass_matrix, mechanics, parameters)
        F = with_parameters(
            mechanics.forcing - sympy.Matrix(mechanics.generalized_forces), mechanics, parameters
        )
        functions["M"] = vectorize(list(M), args)
        functions["F"] = vectorize(list(F), args)
    cache[key] = functions
    return functions


def _derivatives(mechanics: Mechanics, L: sympy.Expr) -> tuple[list, ...]:
    """dL/dq, dL/dqdot and the n*n blocks d2L/dqdot dqdot, d2L/dq dqdot, d2L/dq dq (row
    major), by symengine where it can (sympy took seconds for a five-link chain)."""
    q, v = mechanics.q, mechanics.qdot
    engine = Calculus(mechanics.scene.symbols.values())
    try:
        e = engine.to_engine(L)
        qs, vs = [engine.variable(a) for a in q], [engine.variable(a) for a in v]
        Lq = [e.diff(a) for a in qs]
        Lv = [e.diff(a) for a in vs]
        blocks = (
            [d.diff(b) for d in Lv for b in vs],
            [d.diff(b) for d in Lq for b in vs],
            [d.diff(b) for d in Lq for b in qs],
        )
        back = engine.to_sympy
        return [back(d) for d in Lq], [back(d) for d in Lv], *([back(d) for d in b] for b in blocks)
    except Unsupported:
        pass
    Lq = [sympy.diff(L, a) for a in q]
    Lv = [sympy.diff(L, a) for a in v]
    return (
        Lq,
        Lv,
        [sympy.diff(e, b) for e in Lv for b in v],
        [sympy.diff(e, b) for e in Lq for b in v],
        [sympy.diff(e, b) for e in Lq for b in q],
    )


def _hessian_blocks(mechanics, parameters, t, q, qdot):
    n = mechanics.n
    functions = _functions(mechanics, parameters)
    cols = _columns(t, q, qdot)
    return tuple(functions[key](*cols).T.reshape(len(t), n, n) for key in ("Lvv", "Lqv", "Lqq"))
