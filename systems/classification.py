"""The textbook's classification of a mechanical system, decided from its equations.

The chapter classifies a system by its constraints (scleronomic or rheonomic, holonomic or
nonholonomic, bilateral or unilateral) and by its forces (conservative or not), and calls
it *simple* when it is scleronomic, holonomic and conservative. ``classify`` answers each
question for a derived system; ``Classification`` holds the answers.

What each answer is decided from:

time_dependent
    Either form of the equations of motion, Lagrange's ``M(q, t) qddot = F(q, qdot, t)``
    (driving forces included) or Hamilton's, contains t explicitly. The test is numerical
    (the expression at two times, at random states), so a t that cancels
    (``sin(w t)**2 + cos(w t)**2``) does not count, and a t in the drawing never does.
conservative
    Every generalized force comes from a potential without explicit t, and no dissipation
    acts: the enabled effects are Q = G(q) qdot + f(q) with G antisymmetric and closed
    (a magnetic-type force) and f curl-free, and Lagrange's equations ``M qddot = F``
    contain no explicit t. Deciding from the equations makes two ways of writing the same
    dynamics agree: a pendulum whose support is shaken, written with A w sin(w t) in T or
    with the equivalent inertial force in V, is not conservative either way, while an L
    that differs from a t-free one by a total time derivative dF(q, t)/dt is. For a
    Hamiltonian whose Legendre transform does not invert, Hamilton's equations are used.
rheonomic
    The constraints or the transformation r_i(q, t) depend on t explicitly. A scene given
    by T and V shows its transformation only through T = sum m |dr/dt|**2 / 2 =
    T2 + T1 + T0: it is rheonomic when T contains t explicitly, or has a part linear in
    (T1) or free of (T0) the velocities, which are zero exactly when no r_i depends on t
    (the bead on a hoop written in the rotating frame is rheonomic; its H is conserved).
    A t in V alone is read as a time-dependent applied field (a driving force), not as a
    moving constraint: such a scene is time dependent and not conservative, but
    scleronomic. A scene given by L or H is rheonomic when the part that depends on the
    velocities (L - L0, or H - H0) contains t explicitly in a way no total time
    derivative dF(q, t)/dt removes: in the mass matrix d2L/dqdot2 or in the antisymmetric
    part of dp_i/dq_j (which dF/dt, adding F_q to p, leaves alone), so that L and
    L + dF/dt classify alike; a part of L linear in the velocities without t is read as a
    velocity-dependent potential (the magnetic L = m v**2/2 + q B (x y_dot - y x_dot)/2),
    not as a moving frame.
holonomic, bilateral
    True unless nonholonomic (velocity) or unilateral (inequality) constraints are
    declared (``Constraints``); a constraint that contains t, or a velocity constraint with
    a part free of the velocities, makes the system rheonomic. Such a constraint moves:
    its force does work, so H is not conserved (and a t in it makes the equations time
    dependent). Impacts on unilateral constraints are
    elastic unless the scene has a ``restitution`` parameter; with one (a slider that may
    go below 1) the system is not conservative and H is not conserved.
hamiltonian_is_energy
    For a scene given by T and V: H (as Jacobi's h = sum qdot dL/dqdot - L) equals T + V
    identically; this is H = T2 - T0 + V, so it holds when the transformation is
    scleronomic and T is a quadratic form in the velocities. For a scene given by L or H
    only, the energy is Jacobi's h of the Lagrangian (Landau and Lifshitz, section 6),
    which H is: true when L (or H) has no explicit t and its velocity part is a positive
    kinetic energy at rest (the magnetic particle, whose H is its kinetic energy, and the
    relativistic particle, whose H = gamma m c**2 + V); None otherwise, where no energy
    can be named: L or H depends on t explicitly (T and V cannot be told apart in a
    time-dependent L), or its velocity part is not a positive kinetic energy.
hamiltonian_conserved, natural, separable
    H has no explicit t, no effect does work (dH/dt = H_t + Q . qdot: an effect whose
    power Q . qdot vanishes identically, a gyroscopic or magnetic force, keeps H), no
    constraint moves (its force then does work) and no impact is inelastic; T is
    quadratic in the velocities (the derivation decides); H = T(p) + V(q, t) (likewise).
gauge_time
    Lagrange's equations contain no t while H (or Hamilton's equations) does: t enters L
    only through a total time derivative dF(q, t)/dt. These answers describe H and the
    canonical variables, which dF/dt changes (p gains F_q, H gains -F_t): H is then not
    conserved and not the energy, while the motion is that of L without dF/dt, whose
    energy ``gauge_energy`` forms (``Mechanics.conserved["E"]``).
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sympy

from systems.calculus import numeric_evaluator, numeric_matrix
from systems.expressions import as_expr

if TYPE_CHECKING:
    from systems.scene import Scene

TOLERANCE = 1e-9
"""Relative tolerance of the numerical zero tests."""

SAMPLES = 4
"""Random states at which an identity must hold (more are tried where one cannot be
evaluated)."""


@dataclass(frozen=True)
class Constraints:
    """The constraints a scene declares, as expressions in (q, qdot, t) and parameters.

    Filled from a scene's ``[constraints]`` table (``systems.constraints.declared``) and
    passed to ``classify``.

    Attributes
    ----------
    holonomic : tuple of sympy.Expr
        f(q, t) = 0.
    nonholonomic : tuple of sympy.Expr
        Linear in the velocities: a(q, t) . qdot + b(q, t) = 0.
    unilateral : tuple of sympy.Expr
        g(q, t) >= 0.
    """

    holonomic: tuple[sympy.Expr, ...] = ()
    nonholonomic: tuple[sympy.Expr, ...] = ()
    unilateral: tuple[sympy.Expr, ...] = ()


NO_CONSTRAINTS = Constraints()


@dataclass(frozen=True)
class Classification:
    """The textbook's classification of a mechanical system (see the module docstring).

    Attributes
    ----------
    time_dependent : bool
        The equations of motion contain t explicitly (driving forces count).
    conservative : bool
        Every force comes from a potential without explicit t; no dissipation.
    hamiltonian_conserved : bool
        H has no explicit t and no effects act.
    hamiltonian_is_energy : bool or None
        H equals the mechanical energy; None where no energy can be named.
    natural : bool
        T is a quadratic form in the velocities.
    separable : bool
        H = T(p) + V(q, t).
    rheonomic : bool
        The constraints or the transformation r_i(q, t) depend on t explicitly.
    holonomic : bool
        No nonholonomic constraint.
    bilateral : bool
        No unilateral constraint.
    simple : bool
        Scleronomic, holonomic and conservative.
    dissipative : tuple of str or None
        H has no explicit t, no constraint moves, and the effects' power
        ``sum Q_i qdot_i`` is provably never positive and not identically zero (damping):
        H can only decrease. The names are the parameters that proof takes as positive
        (their values in the scene are); None where H is conserved or may grow.
    gauge_time : bool
        L contains t only through a total time derivative dF(q, t)/dt: Lagrange's
        equations do not contain t, while the momenta p = dL/dqdot, H and Hamilton's
        equations do. H is then not the energy and not conserved; the energy of L
        without dF/dt is (``Mechanics.conserved["E"]`` where it could be formed).
    """

    time_dependent: bool
    conservative: bool
    hamiltonian_conserved: bool
    hamiltonian_is_energy: bool | None
    natural: bool
    separable: bool
    rheonomic: bool
    holonomic: bool
    bilateral: bool
    simple: bool
    dissipative: tuple[str, ...] | None = None
    gauge_time: bool = False

    def as_dict(self) -> dict[str, bool | None]:
        """The answers by name, as ``derive --json`` prints them (None is null)."""
        return {
            "time_dependent": self.time_dependent,
            "conservative": self.conservative,
            "hamiltonian_conserved": self.hamiltonian_conserved,
            "hamiltonian_is_energy": self.hamiltonian_is_energy,
            "natural": self.natural,
            "separable": self.separable,
            "rheonomic": self.rheonomic,
            "holonomic": self.holonomic,
            "bilateral": self.bilateral,
            "simple": self.simple,
            "dissipative": self.dissipative is not None,
            "gauge_time": self.gauge_time,
        }

    def describe(self) -> list[str]:
        """The classification in the textbook's words, one sentence each."""
        return [
            describe_rheonomic(self.rheonomic),
            describe_holonomic(self.holonomic),
            describe_bilateral(self.bilateral),
            describe_conservative(self.conservative),
            describe_simple(self.simple),
            describe_time_dependent(self.time_dependent, gauge_time=self.gauge_time),
            describe_hamiltonian_conserved(self.hamiltonian_conserved, gauge_time=self.gauge_time),
            describe_energy(self.hamiltonian_is_energy),
            "natural (T quadratic in velocities)" if self.natural else "not natural",
            "separable: H = T(p) + V(q)" if self.separable else "not separable",
        ]


def describe_rheonomic(rheonomic: bool) -> str:
    """Scleronomic or rheonomic, in the textbook's words."""
    if rheonomic:
        return "rheonomic: the constraints or the transformation r(q, t) depend on t"
    return "scleronomic: the constraints and the transformation r(q) do not depend on t"


def describe_holonomic(holonomic: bool) -> str:
    """Holonomic or not, in the textbook's words."""
    if holonomic:
        return "holonomic: every constraint is an equation f(q, t) = 0"
    return "nonholonomic: a constraint on the velocities cannot be integrated to f(q, t) = 0"


def describe_bilateral(bilateral: bool) -> str:
    """Bilateral or unilateral, in the textbook's words."""
    if bilateral:
        return "bilateral: the constraints are equalities"
    return "unilateral: a constraint is an inequality (a wall, a floor)"


def describe_conservative(conservative: bool) -> str:
    """Conservative or not, in the textbook's words."""
    if conservative:
        return "conservative: every force comes from a potential without explicit t"
    return "not conservative: dissipation, a driving force or a time-dependent potential acts"


def describe_simple(simple: bool) -> str:
    """Simple or general, in the textbook's words."""
    if simple:
        return "simple system: scleronomic, holonomic and conservative"
    return "general system: not scleronomic, holonomic and conservative all at once"


def describe_time_dependent(time_dependent: bool, *, gauge_time: bool = False) -> str:
    """Time dependent or autonomous, in the textbook's words.

    With ``gauge_time`` (L contains t only through a total time derivative) Lagrange's
    equations are autonomous and only H and the canonical form carry t.
    """
    if gauge_time:
        return (
            "autonomous motion: Lagrange's equations do not contain t; L contains it only "
            "through a total time derivative dF(q, t)/dt, which puts t into H (and, where "
            "F depends on q, into the momenta p = ∂L/∂q̇ and Hamilton's "
            "equations) but does not change the motion"
        )
    if time_dependent:
        return "time dependent: t appears explicitly in the equations of motion"
    return "autonomous: the equations of motion do not contain t"


def describe_hamiltonian_conserved(conserved: bool, *, gauge_time: bool = False) -> str:
    """Whether H is conserved, and why not where L has a total time derivative."""
    if conserved:
        return "H is conserved"
    if gauge_time:
        return "H is not conserved: it contains t through the total time derivative dF/dt in L"
    return "H is not conserved"


def describe_cyclic(cyclic, conserved, shown=None) -> str:
    """``"cyclic coordinates: θ"``: the coordinates absent from L (``Mechanics.cyclic``),
    saying which of their momenta are not conserved (an effect or a constraint acts along
    them: dissipation on a free coordinate), so the line never reads as a conservation
    law the derivation does not list.

    ``conserved`` holds the names of the conserved quantities (``"p_<q>"``), ``shown``
    maps scene names to display names.
    """
    shown = shown or {}
    if not cyclic:
        return "cyclic coordinates: none"
    names = ", ".join(shown.get(q, q) for q in cyclic)
    lost = [q for q in cyclic if f"p_{q}" not in conserved]
    if not lost:
        return f"cyclic coordinates: {names}"
    momenta = ", ".join(f"p_{shown.get(q, q)}" for q in lost)
    verb = "is" if len(lost) == 1 else "are"
    return (
        f"cyclic coordinates: {names} (absent from L; {momenta} {verb} not conserved: an "
        "effect or a constraint acts along it)"
    )


def describe_energy(is_energy: bool | None) -> str:
    """H against the mechanical energy, in the textbook's words."""
    if is_energy is None:
        return "H = T + V undecided: no energy can be named from L (or H) alone"
    return "H = T + V, the mechanical energy" if is_energy else "H differs from T + V"


def classify(
    scene: Scene,
    *,
    t: sympy.Symbol,
    q: Sequence[sympy.Symbol],
    qdot: Sequence[sympy.Symbol],
    p: Sequence[sympy.Symbol],
    lagrangian: sympy.Expr | None,
    kinetic: sympy.Expr | None,
    potential: sympy.Expr | None,
    hamiltonian: sympy.Expr,
    mass_matrix: sympy.Matrix | None,
    forcing: sympy.Matrix | None,
    momenta: Sequence[sympy.Expr] | None,
    hamilton_equations: Sequence[sympy.Expr],
    forces: Sequence[sympy.Expr],
    natural: bool,
    separable: bool,
    matrix_form=None,
    constraints: Constraints = NO_CONSTRAINTS,
) -> Classification:
    """Classify a derived system as the textbook does.

    Parameters
    ----------
    scene : Scene
        Its ``kind`` says what the user gave: T and V, L, or H.
    t, q, qdot, p : sympy.Symbol and sequences of them
        Time, coordinates, velocities and momenta.
    lagrangian : sympy.Expr or None
        L(q, qdot, t); None for a Hamiltonian whose Legendre transform does not invert.
    kinetic, potential : sympy.Expr or None
        T and V; only read for a scene given by T and V.
    hamiltonian : sympy.Expr
        H(q, p, t) (in matrix form, with qdot standing for M^-1 (p - a)).
    mass_matrix, forcing : sympy.Matrix or None
        M and F of Lagrange's equations ``M qddot = F`` (F with the effects).
    momenta : sequence of sympy.Expr or None
        p_i(q, qdot, t).
    hamilton_equations : sequence of 2n sympy.Expr
        (qdot_1.., pdot_1..) in (q, p, t), or in (q, qdot, t) for matrix form.
    forces : sequence of n sympy.Expr
        Generalized forces Q_i(q, qdot, t) of the enabled effects.
    natural, separable : bool
        As the derivation decided them.
    matrix_form : systems.mechanics.MatrixForm or None
    constraints : Constraints
        Declared constraints (none by default).

    Returns
    -------
    Classification
    """
    probe = _Probe()
    q, qdot, p = tuple(q), tuple(qdot), tuple(p)
    n = len(q)
    acting = any(not probe.identical(Q, 0) for Q in forces)
    # an effect whose power sum Q_i qdot_i vanishes identically (a gyroscopic or magnetic
    # force) does no work: dH/dt = dH/dt (explicit) + Q . qdot keeps H as it is
    workless = acting and _workless(forces, qdot, probe)
    from_potential = not acting or _forces_from_potential(forces, q, qdot, t, probe)

    lagrange = []
    if mass_matrix is not None and forcing is not None:
        lagrange = [*mass_matrix, *forcing]
    if matrix_form is not None:
        # qdot in Hamilton's equations stands for M(q, t)^-1 (p - a(q, t))
        hamilton = [*matrix_form.mass_matrix, *matrix_form.shift, *hamilton_equations[n:]]
    else:
        hamilton = list(hamilton_equations)
    lagrange_t = any(probe.depends_on(e, (t,)) for e in lagrange)
    hamilton_t = any(probe.depends_on(e, (t,)) for e in hamilton)
    # a moving constraint puts t into the equations (through its force) and does work;
    # so does a nonholonomic one with a velocity-free part b (x_dot - v0 = 0 is x = v0 t)
    every = (*constraints.holonomic, *constraints.nonholonomic, *constraints.unilateral)
    explicit = any(probe.depends_on(as_expr(c), (t,)) for c in every)
    zero_velocity = dict.fromkeys(qdot, sympy.S.Zero)
    moving = explicit or any(
        not probe.identical(as_expr(c).xreplace(zero_velocity), 0) for c in constraints.nonholonomic
    )
    time_dependent = lagrange_t or hamilton_t or explicit
    # impacts with a coefficient of restitution (a slider, which may be below 1) take
    # energy away; without that parameter they are elastic
    inelastic = bool(constraints.unilateral) and "restitution" in dict(scene.parameters)
    conservative = from_potential and not (lagrange_t if lagrange else hamilton_t)
    conservative = conservative and not inelastic

    H_explicit_t = probe.depends_on(hamiltonian, (t,)) or (
        matrix_form is not None and any(probe.depends_on(e, (t,)) for e in matrix_form.mass_matrix)
    )
    working = acting and not workless
    hamiltonian_conserved = not working and not H_explicit_t and not moving and not inelastic
    # Lagrange's equations without t while H has it: t enters L only through a total
    # time derivative dF(q, t)/dt (p = dL/dqdot carries F_q, H carries -F_t), which
    # changes H and Hamilton's equations but not the motion
    gauge_time = bool(lagrange) and not lagrange_t and not explicit
    gauge_time = gauge_time and (hamilton_t or H_explicit_t)

    kind = scene.kind
    if kind == "energies":
        rheonomic = _kinetic_energy_is_rheonomic(kinetic, qdot, t, probe)
    elif kind == "lagrangian":
        rheonomic = probe.depends_on(_velocity_part(lagrangian, qdot), (t,))
    else:
        rheonomic = probe.depends_on(_velocity_part(hamiltonian, p), (t,))
    if rheonomic and kind != "energies" and lagrange and momenta is not None:
        # L and L + dF(q, t)/dt classify alike: only what the equations see counts
        rheonomic = _velocity_part_rheonomic(mass_matrix, momenta, q, t, probe)
    rheonomic = rheonomic or _constraints_rheonomic(constraints, qdot, t, probe)

    if kind == "energies":
        h = sum((v * m for v, m in zip(qdot, momenta, strict=True)), sympy.S.Zero) - lagrangian
        is_energy: bool | None = probe.identical(h, kinetic + potential)
    else:
        given = lagrangian if kind == "lagrangian" else hamiltonian
        is_energy = None
        if (
            not probe.depends_on(given, (t,)) or (gauge_time and not rheonomic)
        ) and _positive_kinetic_form(mass_matrix, hamilton_equations[:n], qdot, p, probe):
            # with a total time derivative in L, the energy is that of L without it; the
            # H of these momenta differs from it by -dF/dt
            is_energy = not gauge_time

    holonomic = not constraints.nonholonomic
    bilateral = not constraints.unilateral
    return Classification(
        time_dependent=bool(time_dependent),
        conservative=bool(conservative),
        hamiltonian_conserved=bool(hamiltonian_conserved),
        hamiltonian_is_energy=is_energy,
        natural=bool(natural),
        separable=bool(separable),
        rheonomic=bool(rheonomic),
        holonomic=holonomic,
        bilateral=bilateral,
        simple=bool(not rheonomic and holonomic and conservative),
        dissipative=(
            _dissipation(scene, forces, qdot)
            if working and not H_explicit_t and not moving and not inelastic
            else None
        ),
        gauge_time=gauge_time,
    )


DISSIPATION_MAX_OPS = 400
"""Largest effects' power (sympy's operation count) whose sign is looked at."""


def _dissipation(scene: Scene, forces, qdot) -> tuple[str, ...] | None:
    """The parameters (positive in the scene) under which ``sum Q_i qdot_i <= 0`` for
    every state, as sympy proves it; None if it cannot."""
    power = sum((as_expr(Q) * v for Q, v in zip(forces, qdot, strict=True)), sympy.S.Zero)
    if sympy.count_ops(power) > DISSIPATION_MAX_OPS:
        return None
    values = scene.parameter_values
    symbols = scene.symbols
    positive = {
        symbols[name]: sympy.Symbol(name, positive=True)
        for name, value in values.items()
        if value > 0 and name in symbols
    }
    try:
        proved = (-power.xreplace(positive)).is_nonnegative
    except (TypeError, ValueError, RecursionError):
        return None
    if proved is not True:
        return None
    used = {str(s) for s in power.free_symbols}
    return tuple(name for name in values if name in used and values[name] > 0)


# -- the questions ---------------------------------------------------------------------------


def _workless(forces, qdot, probe: _Probe) -> bool:
    power = sum((as_expr(Q) * v for Q, v in zip(forces, qdot, strict=True)), sympy.S.Zero)
    return probe.identical(power, 0)


def does_no_work(forces: Sequence[sympy.Expr], qdot: Sequence[sympy.Symbol]) -> bool:
    """True if effects with generalized forces Q_i(q, qdot, t) do no work: their power
    ``sum Q_i qdot_i`` vanishes identically (at random states), as that of a magnetic or
    gyroscopic force Q = G qdot with G antisymmetric does. No forces do no work."""
    probe = _Probe()
    if all(probe.identical(Q, 0) for Q in forces):
        return True
    return _workless(forces, tuple(qdot), probe)


GAUGE_SECONDS = 2.0
"""CPU seconds given to sympy's integral in ``gauge_energy``."""


def gauge_energy(
    lagrangian: sympy.Expr,
    momenta: Sequence[sympy.Expr],
    q: Sequence[sympy.Symbol],
    qdot: Sequence[sympy.Symbol],
    t: sympy.Symbol,
) -> tuple[sympy.Expr, sympy.Expr] | None:
    """The conserved energy and the potential of an L whose t is a total time derivative.

    For ``L = f(q, qdot) + a(q, t) . qdot + L0(q, t)`` whose Lagrange equations contain
    no t (``Classification.gauge_time``), ``a_t - dL0/dq`` is free of t and is the
    gradient of U(q), the potential of L without its total time derivative dF(q, t)/dt:
    ``U(q) = -L0(q, 0) + int_0^1 q . a_t(s q, 0) ds``. Along a motion on which no effect
    or constraint does work, ``E = h + L0 + U`` (h = qdot . p - L, Jacobi's energy
    function, which the total derivative changes by -F_t) is conserved: dE/dt = -L_t +
    dL0/dt + U_q . qdot = 0. E is the energy of L - dF/dt; H of these momenta is E - F_t.

    Returns
    -------
    (E, U) in (q, qdot, t) and in q, or None where sympy cannot form the integral in
    ``GAUGE_SECONDS`` of CPU time.
    """
    from systems.cpu_limit import TimeLimitExceeded, cpu_limit

    zero = dict.fromkeys(qdot, sympy.S.Zero)
    L0 = as_expr(lagrangian).xreplace(zero)
    rest = [as_expr(m).xreplace(zero) for m in momenta]
    s = sympy.Dummy("s", real=True)
    along = {x: s * x for x in q}
    integrand = sympy.Add(
        *[
            x * sympy.diff(a, t).xreplace({t: sympy.S.Zero}).xreplace(along)
            for x, a in zip(q, rest, strict=True)
        ]
    )
    try:
        with cpu_limit(GAUGE_SECONDS, "the potential of a total time derivative"):
            try:
                integral = sympy.integrate(sympy.expand(integrand), (s, 0, 1))
            except (NotImplementedError, ValueError, TypeError):
                return None
    except TimeLimitExceeded:
        return None
    if integral.has(sympy.Integral, s, sympy.oo, sympy.zoo, sympy.nan):
        return None  # not formed, or singular along the path from q = 0
    U = -L0.xreplace({t: sympy.S.Zero}) + integral
    h = sympy.Add(*[v * m for v, m in zip(qdot, momenta, strict=True)]) - lagrangian
    return h + L0 + U, U


def _velocity_part_rheonomic(mass_matrix, momenta, q, t, probe: _Probe) -> bool:
    """True if what a total time derivative dF(q, t)/dt cannot change depends on t.

    Adding dF/dt to L adds F_q to the momenta and F_t to L: its velocity Hessian
    d2L/dqdot2 (the mass matrix) and the antisymmetric part of dp_i/dq_j (the gyroscopic
    or magnetic field, F_q_iq_j being symmetric) are unchanged. A t in either is a moving
    frame or a field that changes with time; a t elsewhere in the velocity part of L is
    a total derivative (and a driving field, which the equations show).
    """
    if any(probe.depends_on(entry, (t,)) for entry in mass_matrix):
        return True
    n = len(q)
    derivatives = [[sympy.diff(as_expr(momenta[i]), q[j]) for j in range(n)] for i in range(n)]
    return any(
        probe.depends_on(derivatives[i][j] - derivatives[j][i], (t,))
        for i in range(n)
        for j in range(i + 1, n)
    )


def _velocity_part(expr: sympy.Expr, gens: Sequence[sympy.Symbol]) -> sympy.Expr:
    """``expr`` minus its value at zero ``gens``: L - L0, or H - H0."""
    return as_expr(expr) - as_expr(expr).xreplace(dict.fromkeys(gens, sympy.S.Zero))


def _kinetic_energy_is_rheonomic(kinetic, qdot, t, probe: _Probe) -> bool:
    """True if T shows a transformation r(q, t): explicit t, or T1 or T0 not zero.

    T1 is the odd part (T(qdot) - T(-qdot))/2 and T0 = T(qdot = 0); with T = sum m |v|^2/2
    and v = (dr/dq) qdot + dr/dt both vanish exactly when every dr/dt does.
    """
    kinetic = as_expr(kinetic)
    if probe.depends_on(kinetic, (t,)):
        return True
    rest = kinetic.xreplace(dict.fromkeys(qdot, sympy.S.Zero))
    if not probe.identical(rest, 0):
        return True
    mirrored = kinetic.xreplace({v: -v for v in qdot})
    return not probe.identical(kinetic, mirrored)


def _constraints_rheonomic(constraints: Constraints, qdot, t, probe: _Probe) -> bool:
    """True if a declared constraint contains t, or a velocity constraint has a part free
    of the velocities (``x_dot - v0 = 0`` integrates to ``x - v0 t = 0``)."""
    every = (*constraints.holonomic, *constraints.nonholonomic, *constraints.unilateral)
    if any(probe.depends_on(as_expr(c), (t,)) for c in every):
        return True
    zero = dict.fromkeys(qdot, sympy.S.Zero)
    return any(not probe.identical(as_expr(c).xreplace(zero), 0) for c in constraints.nonholonomic)


def _forces_from_potential(forces, q, qdot, t, probe: _Probe) -> bool:
    """True if Q_i = sum_j G_ij(q) qdot_j + f_i(q) comes from a generalized potential
    without explicit t: G antisymmetric and closed (dG = 0, as a magnetic field is) and f
    curl-free. Such forces do what a term of L would; anything else (dissipation, a
    driving force, a force with a curl) is not conservative."""
    n = len(q)
    forces = [as_expr(Q) for Q in forces]
    if any(probe.depends_on(Q, (t,)) for Q in forces):
        return False
    G = [[sympy.diff(forces[i], qdot[j]) for j in range(n)] for i in range(n)]
    if any(probe.depends_on(G[i][j], qdot) for i in range(n) for j in range(n)):
        return False  # not affine in the velocities
    zero = dict.fromkeys(qdot, sympy.S.Zero)
    G = [[entry.xreplace(zero) for entry in row] for row in G]
    f = [Q.xreplace(zero) for Q in forces]
    for i in range(n):
        if not probe.identical(G[i][i], 0):
            return False
        for j in range(i + 1, n):
            if not probe.identical(G[i][j], -G[j][i]):
                return False
            if not probe.identical(sympy.diff(f[i], q[j]), sympy.diff(f[j], q[i])):
                return False
    for i in range(n):
        for j in range(i + 1, n):
            for k in range(j + 1, n):
                cyclic = (
                    sympy.diff(G[i][j], q[k])
                    + sympy.diff(G[j][k], q[i])
                    + sympy.diff(G[k][i], q[j])
                )
                if not probe.identical(cyclic, 0):
                    return False
    return True


def _positive_kinetic_form(mass_matrix, velocities, qdot, p, probe: _Probe) -> bool:
    """True if the velocity part of L is a positive kinetic energy at rest: d2L/dqdot2 at
    qdot = 0 (or, for a Hamiltonian that does not invert, d2H/dp2 at p = 0) is positive
    definite at random positions."""
    if mass_matrix is not None:
        matrix = mass_matrix.xreplace(dict.fromkeys(qdot, sympy.S.Zero))
    else:
        matrix = sympy.Matrix([[sympy.diff(v, pj) for pj in p] for v in velocities])
        matrix = matrix.xreplace(dict.fromkeys(p, sympy.S.Zero))
    return probe.positive_definite(matrix)


# -- numerical identities --------------------------------------------------------------------


def _close(a: complex, b: complex) -> bool:
    return abs(a - b) <= TOLERANCE * max(1.0, abs(a), abs(b))


class _Probe:
    """Zero and dependence tests at random real states (every symbol in [0.3, 1.7]),
    reproducible: a fixed seed per classification."""

    FAILURES = 3 * SAMPLES
    """States tried beyond ``SAMPLES`` before an expression counts as not evaluable."""

    def __init__(self, seed: int = 20261123):
        self.rng = random.Random(seed)

    def _states(self, free):
        for _ in range(SAMPLES + self.FAILURES):
            yield {s: self.rng.uniform(0.3, 1.7) for s in free}

    def identical(self, a, b) -> bool:
        """True if ``a == b`` identically: exactly, or at ``SAMPLES`` random states.

        An identity that cannot be evaluated anywhere is not taken to hold.
        """
        a, b = as_expr(a), as_expr(b)
        if a == b or a - b == 0:
            return True
        value_a, value_b = numeric_evaluator(a), numeric_evaluator(b)
        free = sorted(a.free_symbols | b.free_symbols, key=str)
        good = 0
        for values in self._states(free):
            try:
                x, y = value_a(values), value_b(values)
            except (TypeError, ValueError, ZeroDivisionError, RuntimeError):
                continue
            if not _close(x, y):
                return False
            good += 1
            if good == SAMPLES:
                return True
        return False

    def depends_on(self, expr, symbols: Sequence[sympy.Symbol]) -> bool:
        """True if ``expr`` changes when ``symbols`` alone change (at random states).

        A symbol that appears but cancels (``sin(t)**2 + cos(t)**2``) does not count; an
        expression that cannot be evaluated anywhere is taken at its word.
        """
        expr = as_expr(expr)
        if not expr.has(*symbols):
            return False
        evaluate = numeric_evaluator(expr)
        free = sorted(expr.free_symbols | set(symbols), key=str)
        good = 0
        for values in self._states(free):
            moved = dict(values)
            moved.update({s: self.rng.uniform(0.3, 1.7) for s in symbols})
            try:
                x, y = evaluate(values), evaluate(moved)
            except (TypeError, ValueError, ZeroDivisionError, RuntimeError):
                continue
            if not _close(x, y):
                return True
            good += 1
            if good == SAMPLES:
                return False
        return good == 0

    def positive_definite(self, matrix: sympy.Matrix) -> bool:
        """True if the symmetric ``matrix`` is positive definite at every random state
        where it can be evaluated (at least one)."""
        free = sorted(matrix.free_symbols, key=str)
        good = 0
        for values in self._states(free):
            try:
                numbers = np.array(numeric_matrix(matrix, values), dtype=complex)
            except (TypeError, ValueError, ZeroDivisionError, RuntimeError):
                continue
            if not np.all(np.isfinite(numbers)) or np.abs(numbers.imag).max(initial=0.0) > 0:
                continue
            real = numbers.real
            if np.linalg.eigvalsh((real + real.T) / 2).min() <= 0:
                return False
            good += 1
            if good == SAMPLES:
                break
        return good > 0
