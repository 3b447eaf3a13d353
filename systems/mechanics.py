"""Derivation: from a scene to Lagrange's and Hamilton's equations, classified.

Coordinates, velocities and momenta are plain real symbols; the total time derivative
is taken by the chain rule. Lagrange's equations are kept as ``M(q, t) qddot = F`` and M
is never inverted symbolically to get the accelerations of a large system (see
``accelerations``). The Legendre transform of a Lagrangian quadratic in the velocities,
``L = qdot.M.qdot/2 + a.qdot + L0``, gives ``qdot = M^-1 (p - a)`` and
``H = (p - a).M^-1.(p - a)/2 - L0``; Hamilton's equations then use the identity
``-dH/dq = dL/dq`` at ``qdot(q, p)``, which keeps them far smaller than differentiating H.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

import sympy

from systems.calculus import Calculus, Unsupported, numeric_evaluator, numeric_matrix, replaced
from systems.classification import Classification, classify, does_no_work, gauge_energy
from systems.cpu_limit import TimeLimitExceeded, cpu_limit, limit_seconds
from systems.display import EXPANSION_LIMIT, expanded_terms
from systems.display import tidied as _tidy
from systems.expressions import as_expr
from systems.legendre import SquareRootTransform, square_root_transform
from systems.scene import Scene
from systems.symmetries import ENERGY, conserved_charges, pushes_along

ZERO_TOLERANCE = 1e-9
SYMBOLIC_INVERSE_LIMIT = 4


class DerivationError(ValueError):
    """The scene cannot be turned into equations of motion; says why and what to fix."""

    def __init__(self, reason: str, *, source: str = "<text>", field: str | None = None):
        self.reason = reason
        self.source = source
        self.field = field
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.field}: " if self.field else ""
        return f"{self.source}: {where}{self.reason}"


@dataclass(frozen=True, eq=False)
class MatrixForm:
    """The Legendre transform of ``L = qdot.M.qdot/2 + a.qdot + L0``, left unsolved.

    For a system in matrix form, the velocity symbols qdot in ``Mechanics.velocities``,
    ``hamiltonian`` and ``hamilton_equations`` stand for the solution of
    ``M(q, t) qdot = p - a(q, t)``, which the kernels solve numerically at every
    evaluation (``systems.matrix_solve``). Nothing of size n**2 or worse is ever formed
    symbolically beyond M itself.

    Attributes
    ----------
    mass_matrix : sympy.Matrix, shape (n, n)
        M(q, t), symmetric; positive definite for a physical kinetic energy.
    shift : sympy.Matrix, shape (n, 1)
        a(q, t), the part of the momenta free of velocities (gyroscopic, moving frames).
    rest : sympy.Expr
        L0(q, t), the Lagrangian at zero velocity (-V for a natural system).
    """

    mass_matrix: sympy.Matrix
    shift: sympy.Matrix
    rest: sympy.Expr
    constant: bool
    """True if M depends on neither q nor t (only on parameters)."""


@dataclass(frozen=True, eq=False)
class Mechanics:
    """Everything derived from a scene. Expressions use the scene's own symbols.

    Attributes
    ----------
    mass_matrix : sympy.Matrix, shape (n, n), or None
        M(q, t) in ``M qddot = F``; None when a Hamiltonian has no Lagrangian.
    forcing : sympy.Matrix, shape (n, 1), or None
        F(q, qdot, t), including the enabled effects.
    momenta : tuple of n expressions in (q, qdot, t), or None
    hamiltonian : expression in (q, p, t)
    velocities : tuple of n expressions qdot_i(q, p, t)
    hamilton_equations : tuple of 2n expressions: (qdot_1..qdot_n, pdot_1..pdot_n)
    generalized_forces : tuple of n expressions Q_i(q, qdot, t) of the enabled effects
    matrix_form : MatrixForm or None
        Set when the Legendre transform is left to the kernels (large systems whose M is
        not diagonal): then ``velocities`` are the velocity symbols themselves and qdot in
        ``hamiltonian`` and ``hamilton_equations`` means M(q, t)^-1 (p - a(q, t)).
    """

    scene: Scene
    t: sympy.Symbol
    q: tuple[sympy.Symbol, ...]
    qdot: tuple[sympy.Symbol, ...]
    p: tuple[sympy.Symbol, ...]
    params: dict[str, sympy.Symbol]
    lagrangian: sympy.Expr | None
    kinetic: sympy.Expr | None
    potential: sympy.Expr | None
    mass_matrix: sympy.Matrix | None
    forcing: sympy.Matrix | None
    momenta: tuple[sympy.Expr, ...] | None
    hamiltonian: sympy.Expr
    velocities: tuple[sympy.Expr, ...]
    hamilton_equations: tuple[sympy.Expr, ...]
    generalized_forces: tuple[sympy.Expr, ...]
    cyclic: tuple[str, ...]
    conserved: dict[str, sympy.Expr]
    classification: Classification
    separable_parts: tuple[sympy.Expr, sympy.Expr] | None = None
    matrix_form: MatrixForm | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def qddot(self) -> tuple[sympy.Symbol, ...]:
        return tuple(sympy.Symbol(f"{q}_ddot", real=True) for q in self.scene.coordinates)

    def accelerations(self) -> tuple[sympy.Expr, ...]:
        """qddot_i(q, qdot, t), solved from ``M qddot = F`` on demand.

        For up to ``SYMBOLIC_INVERSE_LIMIT`` coordinates the solution is formed by LU and
        simplified; larger systems are meant to be solved numerically (``systems.compiled``).
        """
        if "accelerations" not in self._cache:
            if self.mass_matrix is None:
                raise DerivationError(
                    "the Hamiltonian's Legendre transform does not invert, so there are "
                    "no accelerations in terms of velocities; use Hamilton's equations",
                    source=self.scene.source,
                )
            if _is_diagonal(self.mass_matrix):
                solution = [
                    f / m for f, m in zip(self.forcing, self.mass_matrix.diagonal(), strict=True)
                ]
                self._cache["accelerations"] = tuple(_tidy(e) for e in solution)
                return self._cache["accelerations"]
            if self.n > SYMBOLIC_INVERSE_LIMIT:
                raise DerivationError(
                    f"symbolic accelerations are only formed for up to "
                    f"{SYMBOLIC_INVERSE_LIMIT} coordinates",
                    source=self.scene.source,
                )
            solution = self.mass_matrix.LUsolve(self.forcing)
            self._cache["accelerations"] = tuple(_tidy(e) for e in solution)
        return self._cache["accelerations"]

    def lagrange_equations(self) -> tuple[sympy.Eq, ...]:
        """Lagrange's equations as ``sum_j M_ij qddot_j = F_i``."""
        if self.mass_matrix is None:
            return ()
        qdd = sympy.Matrix(self.qddot)
        lhs = self.mass_matrix * qdd
        return tuple(sympy.Eq(lhs[i], _tidy(self.forcing[i])) for i in range(self.n))

    def energy_function(self) -> sympy.Expr | None:
        """Jacobi's energy function h = sum qdot_i p_i - L in (q, qdot, t), or None."""
        if self.lagrangian is None or self.momenta is None:
            return None
        h = sum(v * p for v, p in zip(self.qdot, self.momenta, strict=True)) - self.lagrangian
        return _tidy(h)


def derive(scene: Scene, limited: bool = True) -> Mechanics:
    """Derive the equations of motion, momenta, Hamiltonian and classification.

    A scene derived before (same text, same derivation code) is read from the on-disk
    cache of ``systems.derivation_cache`` instead. ``limited``: within
    ``systems.cpu_limit.limit_seconds()`` of CPU time, which only a process's main
    thread can enforce; False for a scene derived within it elsewhere before (a Dask
    worker's task, in a thread, rebuilding a client's scene).

    Raises
    ------
    DerivationError
        For a singular Legendre transform or one that cannot be inverted, or a
        derivation that runs past ``systems.cpu_limit.limit_seconds()`` of CPU time.
    """
    from systems import derivation_cache

    cached = derivation_cache.load(scene)
    if cached is not None:
        return cached
    derivation_cache.must_compute()
    try:
        with cpu_limit(limit_seconds() if limited else None, "deriving the equations of motion"):
            mechanics = _derive(scene)
            if (
                scene.holonomic_constraints
                or scene.nonholonomic_constraints
                or scene.unilateral_constraints
            ):
                from systems.constraints import check

                check(mechanics)  # independent, fewer than n, and a mass matrix to use
    except TimeLimitExceeded as exc:
        raise DerivationError(
            f"{exc}: some expression is probably far larger once expanded or "
            "differentiated than as written (a high power of a long sum, a tower of powers). "
            "Simplify it, or allow more time with PHASE_EXPLORER_DERIVE_SECONDS",
            source=scene.source,
        ) from None
    derivation_cache.store(mechanics)
    return mechanics


def _derive(scene: Scene) -> Mechanics:
    symbols = scene.symbols
    t = symbols["t"]
    q = tuple(symbols[name] for name in scene.coordinates)
    qd = tuple(symbols[name] for name in scene.velocity_names)
    p = tuple(symbols[name] for name in scene.momentum_names)
    params = {name: symbols[name] for name, _ in scene.parameters}
    ctx = _Context(scene, t, q, qd, p)
    forces = ctx.generalized_forces()
    if scene.kind == "hamiltonian":
        return ctx.from_hamiltonian(scene.expression("system.hamiltonian"), forces, params)
    if scene.kind == "energies":
        kinetic, potential = scene.energies()  # from T and V, or from [particles]
        lagrangian = kinetic - potential
    else:
        lagrangian = scene.expression("system.lagrangian")
        kinetic = potential = None
    return ctx.from_lagrangian(lagrangian, kinetic, potential, forces, params)


class _Context:
    """One derivation. Nothing is simplified here: the kernels take the expressions as
    derived (their common-subexpression elimination finds what cancelling would), and
    what people read is tidied when it is laid out (``systems.display.tidied``, after the
    first block); tidying was 94% of a double pendulum's derivation."""

    def __init__(self, scene: Scene, t, q, qd, p):
        self.scene = scene
        self.t, self.q, self.qd, self.p = t, q, qd, p
        self.n = len(q)
        self.rng = random.Random(1234)

    def fail(self, reason: str, field: str | None = None) -> DerivationError:
        return DerivationError(reason, source=self.scene.source, field=field)

    # -- effects ---------------------------------------------------------------------------

    def generalized_forces(self) -> tuple[sympy.Expr, ...]:
        scene = self.scene
        enabled = set(scene.enabled_effects())
        forces = [sympy.S.Zero] * self.n
        if "dissipation" in enabled:
            rayleigh = scene.expression("effects.dissipation")
            for i, v in enumerate(self.qd):
                forces[i] -= sympy.diff(rayleigh, v)
        for name, _ in scene.forces:
            if f"forces.{name}" in enabled:
                forces[scene.coordinates.index(name)] += scene.expression(f"effects.forces.{name}")
        return tuple(forces)

    # -- zero tests on random states -------------------------------------------------------

    def vanishes(self, expr: sympy.Expr) -> bool:
        """True if ``expr`` is zero identically (exactly, or at random real states)."""
        expr = as_expr(expr)
        if expr == 0:
            return True
        free = sorted(expr.free_symbols, key=str)
        evaluate = numeric_evaluator(expr)
        for _ in range(4):
            values = {s: self.rng.uniform(0.3, 1.7) for s in free}
            try:
                value = evaluate(values)
            except (TypeError, ValueError, ZeroDivisionError, RuntimeError):
                return False
            if not abs(value) <= ZERO_TOLERANCE:
                return False
        return True

    def _random_state(self, extra=()) -> dict:
        names = [*self.q, *self.qd, *self.p, self.t, *extra]
        names += [s for s in self.scene.symbols.values() if s not in names]
        return {s: sympy.Float(self.rng.uniform(0.3, 1.7)) for s in names}

    # -- from a Lagrangian -------------------------------------------------------------------

    def from_lagrangian(self, L, kinetic, potential, forces, params) -> Mechanics:
        q, qd = self.q, self.qd
        if not any(L.has(v) for v in qd):
            raise self.fail(
                "the Lagrangian does not depend on any velocity, so there are no equations "
                "of motion; check the kinetic energy",
                "system.kinetic" if kinetic is not None else "system.lagrangian",
            )
        momenta, hessian, gradient, rest = self.lagrangian_parts(L)
        M = sympy.Matrix(hessian)
        self.check_regular(M, "system.kinetic" if kinetic is not None else "system.lagrangian")
        F = sympy.Matrix([gradient[i] + forces[i] - rest[i] for i in range(self.n)])
        zero_velocity = dict.fromkeys(qd, sympy.S.Zero)
        L0 = L.xreplace(zero_velocity)
        quadratic = _degree_at_most(L, qd, 2)
        matrix_form = energy = transform = None
        if quadratic:
            a = sympy.Matrix([m.xreplace(zero_velocity) for m in momenta])
            if self.needs_matrix_form(M):
                matrix_form = MatrixForm(M, a, L0, constant=False)
                velocities = qd
                shifted = [pi - ai for pi, ai in zip(self.p, a, strict=True)]
                H = sum(s * v for s, v in zip(shifted, qd, strict=True)) / 2 - L0
            else:
                velocities, H = self.legendre_quadratic(M, a, L0)
        elif (transform := self.square_root(L, momenta)) is not None:
            velocities, H, energy = transform.velocities, transform.hamiltonian, transform.energy
        else:
            velocities = self.solve_velocities(momenta)
            H = as_expr(
                sum(pi * vi for pi, vi in zip(self.p, velocities, strict=True))
                - L.xreplace(dict(zip(qd, velocities, strict=True)))
            )
        to_velocities = dict(zip(qd, velocities, strict=True))
        if transform is not None:  # dL/dq at qdot(p) would repeat the root's inverse
            pdot = tuple(
                transform.force[i] + replaced(forces[i], to_velocities) for i in range(self.n)
            )
        elif matrix_form is None:
            pdot = tuple(replaced(gradient[i] + forces[i], to_velocities) for i in range(self.n))
        else:  # the kernels' input, never shown at length: no simplification
            pdot = tuple(gradient[i] + forces[i] for i in range(self.n))
        velocity_part = L - L0 if kinetic is None else kinetic
        if kinetic is None:
            kinetic, potential = L - L0, -L0
        natural = quadratic and self.vanishes(
            _homogeneous_part(velocity_part, qd, 2) - velocity_part
        )
        cyclic = tuple(
            name for name, qi in zip(self.scene.coordinates, q, strict=True) if not L.has(qi)
        )
        return self.finish(
            L=L,
            kinetic=kinetic,
            potential=potential,
            M=M,
            F=F,
            momenta=momenta,
            H=H,
            velocities=velocities,
            pdot=pdot,
            forces=forces,
            params=params,
            cyclic=cyclic,
            natural=natural,
            matrix_form=matrix_form,
            energy=energy,
        )

    def lagrangian_parts(self, L) -> tuple[tuple, list[list], list, list]:
        """(momenta, d2L/dqdot2, dL/dq, dp/dq.qdot + dp/dt) of ``L``; see
        ``systems.calculus.Calculus.lagrangian_parts``. symengine where it can, sympy
        otherwise."""
        q, qd, t, n = self.q, self.qd, self.t, self.n
        try:
            momenta, hessian, gradient, rest = Calculus(
                self.scene.symbols.values()
            ).lagrangian_parts(L, q, qd, t)
            return tuple(momenta), hessian, gradient, rest
        except Unsupported:
            pass
        momenta = tuple(sympy.diff(L, v) for v in qd)
        hessian = [[sympy.diff(momenta[i], qd[j]) for j in range(n)] for i in range(n)]
        gradient = [sympy.diff(L, x) for x in q]
        rest = [
            sum((sympy.diff(momenta[i], q[j]) * qd[j] for j in range(n)), sympy.S.Zero)
            + sympy.diff(momenta[i], t)
            for i in range(n)
        ]
        return momenta, hessian, gradient, rest

    def needs_matrix_form(self, M: sympy.Matrix) -> bool:
        """True if the Legendre transform is left to the kernels: more than
        ``SYMBOLIC_INVERSE_LIMIT`` coordinates, M not diagonal and not constant (a
        constant M's inverse is a matrix of numbers and parameters, cheap to form)."""
        if self.n <= SYMBOLIC_INVERSE_LIMIT or _is_diagonal(M):
            return False
        return bool(M.free_symbols & {*self.q, self.t})

    def check_regular(self, M: sympy.Matrix, field: str) -> None:
        """Refuse a Lagrangian whose velocity Hessian is singular everywhere sampled."""
        for _ in range(3):
            values = self._random_state()
            try:
                matrix = numeric_matrix(M, values)
            except (TypeError, ValueError, RuntimeError):
                continue
            if _well_conditioned(matrix):
                return
        raise self.fail(
            "the Legendre transform is singular: the velocity Hessian d2L/dqdot2 has zero "
            "determinant, so the momenta do not determine the velocities. Every velocity "
            "must enter L quadratically (a velocity that is missing, or enters only "
            "linearly, makes L degenerate)",
            field,
        )

    def legendre_quadratic(self, M, a, L0):
        """qdot(q, p) = M^-1 (p - a) and H = (p - a)^T M^-1 (p - a)/2 - L0 in closed form.

        Sums are built term by term: sympy's matrix products expand every entry, which
        cost more than the rest of a double pendulum's derivation."""
        n = self.n
        shifted = [pi - ai for pi, ai in zip(self.p, a, strict=True)]
        if _is_diagonal(M):  # any size: particles in Cartesian coordinates, lattices
            velocities = tuple(shifted[i] / M[i, i] for i in range(n))
            H = sympy.Add(*[shifted[i] ** 2 / M[i, i] for i in range(n)]) / 2 - L0
            return velocities, H
        if n <= SYMBOLIC_INVERSE_LIMIT:
            det, adjugate = _cofactors(M)
            # unevaluated: 1/det evaluated asks sympy's assumptions about det (16 ms)
            scale = sympy.Pow(det, -1, evaluate=False)
        else:  # constant: see needs_matrix_form
            adjugate, scale = M.inv(method="LU"), sympy.S.One
        rows = [sympy.Add(*[adjugate[i, j] * shifted[j] for j in range(n)]) for i in range(n)]
        velocities = tuple(sympy.Mul(scale, row, evaluate=False) for row in rows)
        quadratic = sympy.Add(*[shifted[i] * rows[i] for i in range(n)])
        H = sympy.Mul(sympy.S.Half, scale, quadratic, evaluate=False) - L0
        return velocities, H

    def square_root(self, L, momenta) -> SquareRootTransform | None:
        """The closed-form transform of a square-root Lagrangian (``systems.legendre``),
        its parameters positive in the scene taken as positive, or None if L is not one
        or the inverse does not give back the momenta at random states."""
        values = self.scene.parameter_values
        positive = tuple(
            symbol for name, symbol in self.scene.symbols.items() if values.get(name, 0) > 0
        )
        transform = square_root_transform(L, self.q, self.qd, self.p, positive)
        if transform is None:
            return None
        to_velocities = dict(zip(self.qd, transform.velocities, strict=True))
        back = [replaced(m, to_velocities) - pi for m, pi in zip(momenta, self.p, strict=True)]
        return transform if all(self.vanishes(e) for e in back) else None

    def solve_velocities(self, momenta):
        equations = [sympy.Eq(m, pi) for m, pi in zip(momenta, self.p, strict=True)]
        try:
            solutions = sympy.solve(equations, self.qd, dict=True)
        except (NotImplementedError, ValueError):
            solutions = []
        for solution in solutions:
            if len(solution) != self.n:
                continue
            velocities = tuple(solution[v] for v in self.qd)
            back = [
                m.xreplace(dict(zip(self.qd, velocities, strict=True))) - pi
                for m, pi in zip(momenta, self.p, strict=True)
            ]
            if all(self.vanishes(e) for e in back):
                return tuple(as_expr(v) for v in velocities)
        raise self.fail(
            "the momenta p = dL/dqdot could not be solved for the velocities, so the "
            "Hamiltonian cannot be formed; write L quadratic in the velocities, or give the "
            "hamiltonian directly",
            "system.lagrangian",
        )

    # -- from a Hamiltonian ------------------------------------------------------------------

    def from_hamiltonian(self, H, forces, params) -> Mechanics:
        q, qd, p = self.q, self.qd, self.p
        if not any(H.has(pi) for pi in p):
            raise self.fail(
                "the Hamiltonian does not depend on any momentum p_<q>", "system.hamiltonian"
            )
        calculus = Calculus(self.scene.symbols.values())
        velocities = tuple(as_expr(v) for v in calculus.gradient(H, p))
        L = momenta = M = F = None
        zero_momentum = dict.fromkeys(p, sympy.S.Zero)
        quadratic = _degree_at_most(H, p, 2)
        # from dH/dp (small), not H (the whole system) differentiated n**2 times
        W = sympy.Matrix([calculus.gradient(v, p) for v in velocities])
        small = self.n <= SYMBOLIC_INVERSE_LIMIT or _is_diagonal(W)
        invertible = quadratic and small and self._regular(W)
        if invertible:
            b = sympy.Matrix([v.xreplace(zero_momentum) for v in velocities])
            if _is_diagonal(W):
                Winv = sympy.diag(*[1 / W[i, i] for i in range(self.n)])
            else:
                Winv = W.inv(method="ADJ")
            momenta_vec = Winv * (sympy.Matrix(qd) - b)
            momenta = tuple(as_expr(e) for e in momenta_vec)
            to_momenta = dict(zip(p, momenta, strict=True))
            L = as_expr(
                sum(m * v for m, v in zip(momenta, qd, strict=True)) - H.xreplace(to_momenta)
            )
            _, hessian, gradient, rest = self.lagrangian_parts(L)
            M = sympy.Matrix(hessian)
            F = sympy.Matrix([gradient[i] + forces[i] - rest[i] for i in range(self.n)])
        to_velocities = dict(zip(qd, velocities, strict=True))
        force = calculus.gradient(H, q)
        pdot = tuple(as_expr(-force[i] + forces[i].xreplace(to_velocities)) for i in range(self.n))
        H0 = H.xreplace(zero_momentum)
        kinetic_p, potential = H - H0, H0
        natural = quadratic and self.vanishes(_homogeneous_part(kinetic_p, p, 2) - kinetic_p)
        kinetic = None
        if momenta is not None:
            kinetic = as_expr(kinetic_p.xreplace(dict(zip(p, momenta, strict=True))))
        cyclic = tuple(
            name for name, qi in zip(self.scene.coordinates, q, strict=True) if not H.has(qi)
        )
        return self.finish(
            L=L,
            kinetic=kinetic,
            potential=potential,
            M=M,
            F=F,
            momenta=momenta,
            H=H,
            velocities=velocities,
            pdot=pdot,
            forces=forces,
            params=params,
            cyclic=cyclic,
            natural=natural,
        )

    def splits(self, H: sympy.Expr) -> bool:
        """True if H = T(p) + V(q, t), tested without differentiating H.

        With x = (q, t), H splits so exactly when H(x, p) + H(x', p') - H(x, p') - H(x', p)
        vanishes for all x, x', p, p'; tested at random states with one evaluator of H
        (the second derivatives d2H/dq dp of a large H cost more than the whole rest of
        the derivation, and so did four substituted copies of H).
        """
        # every symbol of the scene gets a value (walking H for its free symbols alone
        # took longer than the test)
        free = [*self.q, *self.p, self.t, *self.scene.symbols.values()]
        positions, momenta = (*self.q, self.t), self.p
        evaluate = numeric_evaluator(as_expr(H))
        for _ in range(4):
            values = {s: self.rng.uniform(0.3, 1.7) for s in free}
            x_other = {s: self.rng.uniform(0.3, 1.7) for s in positions}
            p_other = {s: self.rng.uniform(0.3, 1.7) for s in momenta}
            try:
                terms = (
                    evaluate(values),
                    evaluate(values | x_other | p_other),
                    -evaluate(values | p_other),
                    -evaluate(values | x_other),
                )
            except (TypeError, ValueError, ZeroDivisionError, RuntimeError):
                return False
            scale = max(1.0, *(abs(term) for term in terms))
            if not abs(sum(terms)) <= ZERO_TOLERANCE * scale:
                return False
        return True

    def _regular(self, W: sympy.Matrix) -> bool:
        try:
            self.check_regular(W, "system.hamiltonian")
        except DerivationError:
            return False
        return True

    # -- common ------------------------------------------------------------------------------

    def finish(
        self,
        *,
        L,
        kinetic,
        potential,
        M,
        F,
        momenta,
        H,
        velocities,
        pdot,
        forces,
        params,
        cyclic,
        natural,
        matrix_form=None,
        energy=None,
    ) -> Mechanics:
        from systems.constraints import declared

        q, qd, p, t = self.q, self.qd, self.p, self.t
        # a coordinate along which a constraint's force acts is not cyclic (the Cartesian
        # pendulum's L has no x, but its string pulls along x); one that a constraint
        # contains only elsewhere in its row is (the rolling disk's heading)
        cyclic = tuple(name for name in cyclic if not pushes_along(self.scene, name))
        # in matrix form M depends on q (needs_matrix_form), so H cannot split
        separable = matrix_form is None and self.splits(H)
        separable_parts = None
        if separable:
            zero_p = dict.fromkeys(p, sympy.S.Zero)
            V = H.xreplace(zero_p)
            separable_parts = (as_expr(H - V), as_expr(V))
        # decided from the equations of motion, not from L or H as written
        classification = classify(
            self.scene,
            t=t,
            q=q,
            qdot=qd,
            p=p,
            lagrangian=L,
            kinetic=kinetic,
            potential=potential,
            hamiltonian=H,
            mass_matrix=M,
            forcing=F,
            momenta=momenta,
            hamilton_equations=(*velocities, *pdot),
            forces=forces,
            natural=natural,
            separable=separable,
            matrix_form=matrix_form,
            constraints=declared(self.scene),
        )
        H_conserved = classification.hamiltonian_conserved
        conserved: dict[str, sympy.Expr] = {}
        if H_conserved:
            if energy is not None:  # H(q, p(qdot)) as the textbook writes it
                conserved["H"] = energy
            elif momenta is not None:
                to_p = dict(zip(p, momenta, strict=True))
                conserved["H"] = replaced(H, to_p)
            else:
                conserved["H"] = H
        elif (
            classification.gauge_time
            and classification.conservative
            and does_no_work(forces, qd)
            and (energy := gauge_energy(L, momenta, q, qd, t)) is not None
        ):
            conserved[ENERGY] = energy[0]  # H is E - dF/dt: the energy of L - dF/dt
        for name in cyclic:
            i = self.scene.coordinates.index(name)
            if self.vanishes(forces[i]):
                conserved[f"p_{name}"] = momenta[i] if momenta is not None else p[i]
        # Noether's charges beyond the cyclic momenta: L_z, P_x, [symmetries]
        for charge in conserved_charges(
            self.scene,
            t=t,
            q=q,
            qdot=qd,
            p=p,
            lagrangian=L,
            momenta=momenta,
            velocities=velocities,
            pdot=pdot,
            forces=forces,
            listed=conserved,
        ):
            conserved[charge.name] = charge.velocity
        return Mechanics(
            scene=self.scene,
            t=t,
            q=q,
            qdot=qd,
            p=p,
            params=params,
            lagrangian=L,
            kinetic=kinetic,
            potential=potential,
            mass_matrix=M,
            forcing=F,
            momenta=momenta,
            hamiltonian=H,
            velocities=tuple(velocities),
            hamilton_equations=tuple(velocities) + tuple(pdot),
            generalized_forces=forces,
            cyclic=cyclic,
            conserved=conserved,
            classification=classification,
            separable_parts=separable_parts,
            matrix_form=matrix_form,
        )


def _polynomial_degree(expr: sympy.Expr, gens) -> int | None:
    """An upper bound on the degree of ``expr`` in ``gens`` read off its structure (no
    expansion), or None if it is not visibly a polynomial in them."""
    if not expr.has(*gens):
        return 0
    if expr in gens:
        return 1
    if expr.is_Add or expr.is_Mul:
        degrees = [_polynomial_degree(a, gens) for a in expr.args]
        if any(d is None for d in degrees):
            return None
        return max(degrees) if expr.is_Add else sum(degrees)
    if expr.is_Pow and expr.exp.is_Integer and expr.exp >= 0:
        base = _polynomial_degree(expr.base, gens)
        return None if base is None else base * int(expr.exp)
    return None


def _cofactors(M: sympy.Matrix) -> tuple[sympy.Expr, sympy.Matrix]:
    """det(M) and adj(M) of a small square matrix by cofactor expansion, unexpanded.

    Returns
    -------
    det : sympy.Expr
    adjugate : sympy.Matrix, shape (n, n)
        ``M^-1 = adjugate / det``.
    """
    n = M.shape[0]

    def minor(rows: tuple[int, ...], cols: tuple[int, ...]) -> sympy.Expr:
        if len(rows) == 1:
            return M[rows[0], cols[0]]
        return sympy.Add(
            *[
                (-1) ** k * M[rows[0], c] * minor(rows[1:], cols[:k] + cols[k + 1 :])
                for k, c in enumerate(cols)
                if M[rows[0], c] != 0
            ]
        )

    every = tuple(range(n))
    det = minor(every, every)
    if n == 1:
        return det, sympy.Matrix([[1]])
    adjugate = sympy.Matrix(
        n,
        n,
        lambda i, j: (
            (-1) ** (i + j)
            * minor(tuple(r for r in every if r != j), tuple(c for c in every if c != i))
        ),
    )
    return det, adjugate


def _degree_at_most(expr: sympy.Expr, gens, degree: int) -> bool:
    """True if ``expr`` is a polynomial of degree <= ``degree`` in ``gens``.

    Read off the structure first; only a small expression that looks of higher degree (or
    not polynomial) is expanded, since its terms may cancel.
    """
    bound = _polynomial_degree(expr, gens)
    if bound is not None and bound <= degree:
        return True
    if expanded_terms(expr) > EXPANSION_LIMIT:
        return False
    try:
        poly = sympy.Poly(sympy.expand(expr), *gens)
    except sympy.PolynomialError:
        return False
    if any(any(g in c.free_symbols for g in gens) for c in poly.coeffs()):
        return False
    return poly.total_degree() <= degree


def _homogeneous_part(expr: sympy.Expr, gens, degree: int) -> sympy.Expr:
    """The part of degree 1 or 2 of ``expr``, a polynomial of degree <= 2 in ``gens``.

    From f(s) = expr at s * gens = a + b s + c s**2: b = (f(1) - f(-1))/2 and
    c = (f(1) + f(-1))/2 - f(0), so nothing is expanded.
    """
    f_minus = expr.xreplace({g: -g for g in gens})
    f_zero = expr.xreplace(dict.fromkeys(gens, sympy.S.Zero))
    if degree == 1:
        return (expr - f_minus) / 2
    if degree == 2:
        return (expr + f_minus) / 2 - f_zero
    raise ValueError(f"degree {degree}: only 1 and 2")


def _is_diagonal(matrix: sympy.Matrix) -> bool:
    """True if every entry off the diagonal is identically zero (as written, no
    simplification): then the inverse is taken entry by entry, for any size."""
    n = matrix.rows
    return all(matrix[i, j] == 0 for i in range(n) for j in range(n) if i != j)


def _well_conditioned(matrix: list[list[complex]]) -> bool:
    """True if the smallest singular value is not below 1e-9 of the largest.

    A determinant test scales as the n-th power of the entries: it called a twelve-link
    chain's mass matrix singular.
    """
    import numpy as np

    values = np.linalg.svd(np.array(matrix, dtype=complex), compute_uv=False)
    return bool(np.all(np.isfinite(values)) and values[0] > 0 and values[-1] > 1e-9 * values[0])
