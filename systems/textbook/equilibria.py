"""Equilibria by virtual work, their stability, and small oscillations about them.

For a scleronomic system the equilibria (constant q, zero velocities) solve
``dU/dq = 0`` with ``U(q) = -L(q, qdot=0)``: the potential energy, less any velocity-free
part of the kinetic energy (a bead on a spinning hoop has ``U = V - m w^2 R^2 sin^2/2``).
A scene given only by a Hamiltonian that cannot be turned into a Lagrangian uses
``U = H(q, p=0)``.

Small oscillations use the whole quadratic Lagrangian about an equilibrium,
``L2 = qdot^T M qdot/2 + qdot^T C q - q^T K q/2`` with ``K = d2U/dq2`` and
``C = d2L/dqdot dq`` (the terms of L linear in the velocities: a rotating frame, a magnetic
field). Its equations ``M qdd + G qdot + K q = 0``, ``G = C - C^T - B``, are the quadratic
eigenproblem ``det(-w^2 M + i w G + K) = 0``, solved through its 2m x 2m linearisation; a
Hamiltonian-only scene linearises Hamilton's equations instead (``J Hess H``). Effects
that do no work (``Q . qdot = 0`` identically, without explicit t: a magnetic or
gyroscopic force given as a force) enter as ``B = dQ/dqdot`` at rest; other effects are
left out (the equilibria of the conservative part). The
equilibrium is stable when every eigenvalue lies on the imaginary axis (with ``G = 0``:
when U has a minimum; with ``G != 0`` a maximum or saddle of U may be stabilized
gyroscopically), unstable when one has a positive real part.

When K is singular the linearisation cannot decide. U is then followed along the
degenerate directions (the transverse directions relaxed to dU/dq = 0 there, a
Lyapunov-Schmidt reduction): a rise of even order on every side is a degenerate minimum
(stable by the energy, as U = x^4/4), a fall or an odd order is unstable (x^3, -x^4), and
a U that stays flat is a continuum of equilibria. A continuum is followed (curves by
pseudo-arclength continuation) and reported once, as an ``EquilibriumSet``, with the
transverse frequencies; it is neutral along itself.

Coordinates that ``U`` does not depend on (cyclic ones such as the angle of planetary
motion) are not searched: every value is an equilibrium value. They are reported as
``free`` and set to 0; their momenta are held at zero, so the mass matrix used for the
remaining coordinates is the Schur complement ``M_rr - M_rf M_ff^-1 M_fr`` (and the
velocity-linear terms are reduced the same way, to quadratic order).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import sympy

from systems.calculus import Calculus, Unsupported, fast_function
from systems.cpu_limit import TimeLimitExceeded, cpu_limit
from systems.mechanics import EXPANSION_LIMIT, Mechanics, expanded_terms
from systems.symmetries import ENERGY
from systems.textbook._numeric import (
    cache_for,
    fold_angle,
    parameter_values,
    periodic_symbols,
    run_bounded,
    vectorize,
    with_parameters,
)

DEFAULT_HALF_WIDTH = 10.0
SYMBOLIC_TIMEOUT = 2.0
SYMBOLIC_MAX_COORDINATES = 3
SYMBOLIC_MAX_UNKNOWNS = 5
"""With constraints sympy solves for the coordinates and the multipliers together."""
SYMBOLIC_MAX_OPS = 200
Box = Mapping[str, tuple[float, float]]


@dataclass(frozen=True)
class EquilibriumSet:
    """A connected curve or surface of equilibria, reported once.

    Attributes
    ----------
    dimension : int
        1 for a curve, 2 for a surface, ...
    description : str
        For a person: ``"the circle x² + y² = 1"``, ``"the curve x**2/4 + y**2 - 1 = 0"``,
        or ``"a closed curve of equilibria through (1, 0)"``.
    equation : str
        ``f`` of the set ``f(q) = 0`` in the scene's symbols when sympy found one (a
        common factor of dU/dq that vanishes on the set), else "".
    closed : bool
        True for a curve that was followed all the way round.
    points : ndarray, shape (k, n)
        Points along the set in all n coordinates (free ones at 0, angles folded), in
        order along a curve; the equilibria the scan found on the set for a surface.
    momenta : ndarray, shape (k, n)
        The momenta at rest at those points.
    found : int
        How many equilibria of the numeric scan lay on the set (each was one entry before
        the set was recognised).
    """

    dimension: int
    description: str
    equation: str
    closed: bool
    points: np.ndarray
    momenta: np.ndarray
    found: int

    def as_json(self) -> dict:
        """``{"dimension", "description", "equation", "closed", "neutral_along": True}``."""
        return {
            "dimension": int(self.dimension),
            "description": self.description,
            "equation": self.equation or None,
            "closed": bool(self.closed),
            "neutral_along": True,
        }


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium configuration (or one set of them), its stability and normal modes.

    Attributes
    ----------
    q : dict[str, float]
        Every coordinate's value (free coordinates at 0, periodic angles in (-pi, pi]); for
        a set, one point of it.
    stable : bool
        True when every eigenvalue of the linearised motion is on the imaginary axis and,
        if the linearisation is degenerate, U rises along the degenerate directions (for a
        set: transversally; it is neutral along itself).
    kind : str
        What U does there: ``"minimum"``, ``"saddle"``, ``"maximum"``, ``"degenerate"``
        (K has a zero eigenvalue; see ``order`` and ``decided_by``) or ``"continuum"`` (a
        set of equilibria, see ``continuum``).
    frequencies : list[float]
        Normal-mode angular frequencies w (ascending, the zero ones of degenerate or
        neutral directions left out) for a stable equilibrium, else [].
    omega_squared : ndarray, shape (m,)
        Eigenvalues w^2 of ``K v = w^2 M v`` over the m searched coordinates, ascending,
        without the gyroscopic terms; a negative one is the square of a growth rate.
    modes : ndarray, shape (n, m) or (n, k)
        Mode shapes in all n coordinates: without gyroscopic terms column j belongs to
        ``omega_squared[j]``, normalized so that ``v^T M v = 1``; with them (complex) the
        coordinate part of the eigenvector of each of the k positive frequencies, scaled
        so that its largest entry is 1 (a phase of i is a quarter period behind).
    hessian : ndarray, shape (m, m)
        K = d2U/dq2 over the searched coordinates.
    potential : float
        U at the equilibrium, which is also H there: the energy of the level set through
        it (a saddle's level set is the separatrix).
    p : dict[str, float]
        The momenta at rest there (zero unless L has terms linear in the velocities),
        for markers in a phase view.
    exact : dict[str, str]
        Closed forms found by sympy (coordinate -> expression text in the parameters);
        empty when the equilibrium was found numerically.
    eigenvalues : ndarray, shape (2m,)
        Complex eigenvalues of the linearised motion, sorted by imaginary part (empty
        when the inertia there is zero or infinite): ``±i w`` when stable, a positive
        real part is a growth rate.
    gyroscopic : ndarray, shape (m, m)
        G = C - C^T (antisymmetric; zero without velocity-linear terms). For a
        Hamiltonian-only scene, ``d2H/dq dp`` at the equilibrium.
    order : int or None
        For a degenerate equilibrium, the order of the leading term of U along the
        degenerate direction(s) (4 for U = x^4/4); None otherwise or if U is flat.
    decided_by : str
        One sentence: what decided the stability.
    verdict : str
        The same as a key: ``"stable: minimum"``, ``"stable: gyroscopic"``,
        ``"unstable: linear"``, ``"stable: rises"`` (a degenerate minimum),
        ``"unstable: falls"``, ``"unstable: odd"``, ``"stable: flat"``,
        ``"stable: flat gyroscopic"``, ``"unstable: flat"`` or ``"undecided"``.
    continuum : EquilibriumSet or None
        The set this entry stands for (``kind == "continuum"``).
    multipliers : dict[str, float]
        With ``[constraints]``: the multiplier of every constraint in row order
        (``lambda_1``, ...), the constraint force ``-A^T lambda`` that holds the system
        there (0 for a unilateral constraint out of contact); empty without constraints.
    contacts : tuple of str
        The multipliers of the unilateral constraints in contact (g = 0) there.
    chart : str
        "" at a regular point of the chart; at a chart singularity (the mass matrix
        singular there: the pole of polar angles) the sentence that says so, e.g.
        ``"chart singularity at theta = 0: the mass matrix is singular there"``. Such an
        equilibrium was decided in a regular local chart (``systems.textbook.charts``:
        ``frequencies`` with multiplicity, ``modes`` empty) or, where none could be
        formed, is ``"undecided"`` with the reason.
    """

    q: dict[str, float]
    stable: bool
    kind: str
    frequencies: list[float]
    omega_squared: np.ndarray
    modes: np.ndarray
    hessian: np.ndarray
    potential: float
    p: dict[str, float] = field(default_factory=dict)
    exact: dict[str, str] = field(default_factory=dict)
    eigenvalues: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=complex))
    gyroscopic: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    order: int | None = None
    decided_by: str = ""
    verdict: str = ""
    continuum: EquilibriumSet | None = None
    multipliers: dict[str, float] = field(default_factory=dict)
    contacts: tuple[str, ...] = ()
    chart: str = ""

    @property
    def growth_rates(self) -> list[float]:
        """The positive real parts of the eigenvalues (descending), [] when stable."""
        if self.stable or self.eigenvalues.size == 0:
            return []
        scale = max(1.0, float(np.max(np.abs(self.eigenvalues))))
        # one of each conjugate pair: a real rate, or the real part of a growing spiral
        rates = [lam.real for lam in self.eigenvalues if lam.real > 1e-7 * scale and lam.imag >= 0]
        return sorted((float(r) for r in rates), reverse=True)

    def as_json(self) -> dict:
        """``{"q", "stable", "frequencies", "kind", "decided_by"}``, and ``"order"`` for a
        degenerate equilibrium, ``"growth_rates"`` for an unstable one with a growing
        mode, ``"set"`` (``EquilibriumSet.as_json``) for a continuum, ``"multipliers"``
        and ``"contacts"`` for a system with constraints, ``"chart_singularity"`` (the
        ``chart`` sentence) at a singular point of the coordinates."""
        data = {
            "q": {name: _clean(value) for name, value in self.q.items()},
            "stable": bool(self.stable),
            "frequencies": [float(w) for w in self.frequencies] if self.stable else [],
            "kind": self.kind,
            "decided_by": self.decided_by,
        }
        if self.kind == "degenerate":
            data["order"] = self.order
        if not self.stable and self.growth_rates:
            data["growth_rates"] = self.growth_rates
        if self.continuum is not None:
            data["set"] = self.continuum.as_json()
        if self.multipliers:
            data["multipliers"] = {k: _clean(v) for k, v in self.multipliers.items()}
            data["contacts"] = list(self.contacts)
        if self.chart:
            data["chart_singularity"] = self.chart
        return data


@dataclass(frozen=True)
class EquilibriumSearch:
    """The result of a search: the equilibria and how they were found.

    Attributes
    ----------
    equilibria : list[Equilibrium]
        Sorted by U, then by coordinates.
    method : str
        ``"symbolic"`` (sympy solved dU/dq = 0 and a numeric scan found nothing more),
        ``"symbolic+numeric"``, ``"numeric"``, ``"none"`` (not searched: see reason), or
        ``"not computed"`` (a system with constraints: ``not_computed``).
    reason : str
        One sentence for the user: why there are none, or what was assumed.
    searched, free, periodic : tuple[str, ...]
        Coordinates solved for; coordinates U does not depend on (set to 0); coordinates
        folded into (-pi, pi] because the system is 2 pi-periodic in them.
    box : dict[str, tuple[float, float]]
        The numeric search box of each searched coordinate.
    potential : sympy.Expr or None
        The U(q) used, in the scene's symbols (parameters left symbolic).
    multipliers : tuple[str, ...]
        With ``[constraints]``: the names of their multipliers (``lambda_1``, ...), the
        keys of each ``Equilibrium.multipliers``; empty without constraints.
    """

    equilibria: list[Equilibrium]
    method: str
    reason: str
    searched: tuple[str, ...] = ()
    free: tuple[str, ...] = ()
    periodic: tuple[str, ...] = ()
    box: dict[str, tuple[float, float]] = field(default_factory=dict)
    potential: sympy.Expr | None = None
    multipliers: tuple[str, ...] = ()


SEARCH_SECONDS = 15.0
"""Longest an equilibrium search may take (the symbolic part has its own ``timeout``)."""


def find_equilibria(
    mechanics: Mechanics,
    box: Box | None = None,
    *,
    parameters: Mapping[str, float] | None = None,
    symbolic: bool = True,
    timeout: float = SYMBOLIC_TIMEOUT,
) -> list[Equilibrium]:
    """The equilibria of a scleronomic system (see ``search_equilibria``)."""
    return search_equilibria(
        mechanics, box, parameters=parameters, symbolic=symbolic, timeout=timeout
    ).equilibria


def equilibria_json(
    mechanics: Mechanics, box: Box | None = None, *, parameters: Mapping[str, float] | None = None
) -> list[dict] | None:
    """The equilibria for ``derive --json``: a list of ``{"q", "stable", "frequencies"}``,
    or None where they are not computed (``not_computed``: a system with constraints)."""
    if not_computed(mechanics) is not None:
        return None
    return [e.as_json() for e in find_equilibria(mechanics, box, parameters=parameters)]


def equilibrium_potential(mechanics: Mechanics) -> tuple[sympy.Expr, str]:
    """U(q) (parameters symbolic) whose stationary points are the equilibria, and its origin.

    Returns ``(U, source)`` with source ``"lagrangian"`` (U = -L at zero velocities) or
    ``"hamiltonian"`` (U = H at zero momenta). Where L contains t only through a total
    time derivative dF(q, t)/dt (``Classification.gauge_time``) U is that of L - dF/dt:
    the conserved energy ``E`` at rest (``systems.classification.gauge_energy``), so L
    and L + dF/dt have the same equilibria.
    """
    if ENERGY in mechanics.conserved:
        zero = dict.fromkeys(mechanics.qdot, sympy.S.Zero)
        return _expand(mechanics.conserved[ENERGY].xreplace(zero)), "lagrangian"
    if mechanics.lagrangian is not None:
        zero = dict.fromkeys(mechanics.qdot, sympy.S.Zero)
        return _expand(-mechanics.lagrangian.xreplace(zero)), "lagrangian"
    zero = dict.fromkeys(mechanics.p, sympy.S.Zero)
    return _expand(mechanics.hamiltonian.xreplace(zero)), "hamiltonian"


def _expand(expr: sympy.Expr) -> sympy.Expr:
    """``expand(expr)``, unless it would have more terms than anyone would read."""
    return expr if expanded_terms(expr) > EXPANSION_LIMIT else sympy.expand(expr)


def search_equilibria(
    mechanics: Mechanics,
    box: Box | None = None,
    *,
    parameters: Mapping[str, float] | None = None,
    symbolic: bool = True,
    timeout: float = SYMBOLIC_TIMEOUT,
) -> EquilibriumSearch:
    """Solve dU/dq = 0 symbolically where sympy can, and numerically within a box.

    Parameters
    ----------
    mechanics : Mechanics
        From ``systems.mechanics.derive``. Effects (dissipation, forces) are ignored: the
        equilibria are those of the conservative part.
    box : mapping of coordinate name to (low, high), optional
        The region scanned numerically (the view). Defaults: (-pi, pi] for a periodic
        coordinate; otherwise (-10, 10), widened to cover three times the scene's view
        range of the coordinate (``[view] ranges``) if it has one. When a box is given,
        symbolic solutions outside it are dropped too; without one they are all kept.
    parameters : mapping of name to float, optional
        Parameter values overriding the scene's.
    symbolic : bool
        Try ``sympy.solve`` first (stopped after ``timeout`` seconds of CPU time).

    Returns
    -------
    EquilibriumSearch
        Never raises for a scene that derived; ``reason`` explains an empty result. A
        search that runs past ``SEARCH_SECONDS`` is stopped and says so.
    """
    try:
        with cpu_limit(SEARCH_SECONDS, "the equilibrium search"):
            return _search_equilibria(mechanics, box, parameters, symbolic, timeout)
    except TimeLimitExceeded as exc:
        return EquilibriumSearch([], "none", f"{exc} (the potential is too large to scan)")


def not_computed(mechanics: Mechanics) -> str | None:
    """Why the equilibria of ``mechanics`` are not computed (None: they are).

    Holonomic and unilateral constraints are solved with their forces (see
    ``_search_constrained``). Nonholonomic ones are refused where U depends on the
    coordinates: at rest ``a . qdot = 0`` holds everywhere, so the equilibria
    ``dU/dq + a^T lambda = 0`` (n equations in n + k unknowns) form manifolds of dimension
    k, and the linearised motion about them has the stiffness
    ``Z^T (U_qq + sum_i lambda_i da_i/dq) Z``, not symmetric and not a Hessian: Lyapunov's
    first method leaves the k zero roots of the manifold critical, and the energy decides
    only where U itself has a strict minimum. A reduced Hessian would be a wrong answer.
    """
    rows = _constraint_rows(mechanics)
    if rows is None or "nonholonomic" not in rows.kinds:
        return None
    U, _ = equilibrium_potential(mechanics)
    if not U.has(*mechanics.q):
        return None  # every configuration at rest, lambda = 0 (``_search_constrained``)
    return (
        "equilibria of a system with nonholonomic constraints are not computed: at rest "
        "a\u00b7q\u0307 = 0 holds everywhere, so the equilibria \u2202U/\u2202q + "
        "a\u1d40\u03bb = 0 form manifolds, and the stiffness of their linearisation, "
        "Z\u1d40(U_qq + \u03a3\u03bb\u1d62 \u2202a\u1d62/\u2202q)Z, is not symmetric: "
        "neither a reduced Hessian nor Lyapunov's first method (its zero roots are "
        "critical) decides their stability"
    )


def _constraint_rows(mechanics: Mechanics):
    """``systems.constraints.rows(mechanics)`` (None without ``[constraints]``)."""
    from systems.constraints import constrained, rows

    return rows(mechanics) if constrained(mechanics.scene) else None


def _search_equilibria(mechanics, box, parameters, symbolic, timeout) -> EquilibriumSearch:
    names = mechanics.scene.coordinates
    U, source = equilibrium_potential(mechanics)
    reason = not_computed(mechanics)
    if reason is not None:
        return EquilibriumSearch([], "not computed", reason, potential=U)
    expression = mechanics.lagrangian if source == "lagrangian" else mechanics.hamiltonian
    if ENERGY in mechanics.conserved:  # U of L - dF/dt, free of t by construction
        expression = U
    if expression.has(mechanics.t):
        return EquilibriumSearch([], "none", _time_dependent_reason(mechanics), potential=U)
    rows = _constraint_rows(mechanics)
    if rows is not None:
        return _search_constrained(mechanics, rows, U, box, parameters, symbolic, timeout)
    notes = _effects_notes(mechanics)
    if source == "hamiltonian":
        notes.append("U = H(q, p = 0), as the Hamiltonian has no Lagrangian")
    free = tuple(name for name, qi in zip(names, mechanics.q, strict=True) if not U.has(qi))
    searched = tuple(name for name in names if name not in free)
    if free:
        notes.append(f"U does not depend on {', '.join(free)}: free (any value), shown at 0")
    if not searched:
        return EquilibriumSearch(
            [],
            "none",
            "U is constant: every configuration is a (neutral) equilibrium",
            free=free,
            potential=U,
        )
    symbol_of = dict(zip(names, mechanics.q, strict=True))
    unknowns = [symbol_of[name] for name in searched]
    periodic = _periodic(mechanics, expression, unknowns, searched, parameters)
    region = _region(searched, periodic, box, mechanics.scene.view)
    U_numeric = with_parameters(U, mechanics, parameters)
    problem = _Problem(mechanics, U_numeric, unknowns, searched, free, periodic, region, parameters)
    found, method = _locate(
        problem, U, symbolic, timeout, keep_outside=box is None, key=("equilibria.symbolic",)
    )
    problem.equation = _set_equation_finder(
        mechanics, U, unknowns, timeout if symbolic else 0.0, parameters, region
    )
    equilibria = problem.classify(found)
    equilibria.sort(key=lambda e: (round(e.potential, 9), tuple(e.q.values())))
    if not equilibria:
        notes.insert(0, "dU/dq vanishes nowhere in the search box")
    return EquilibriumSearch(
        equilibria,
        method,
        "; ".join(notes),
        searched=searched,
        free=free,
        periodic=periodic,
        box=region,
        potential=U,
    )


def _effects_notes(mechanics: Mechanics) -> list[str]:
    """What the search makes of the enabled effects, as notes."""
    if all(f == 0 for f in mechanics.generalized_forces):
        return []
    if _gyroscopic_effects(mechanics):
        return [
            "the effects do no work (Q\u00b7q\u0307 = 0): they leave the equilibria where "
            "they are and enter the small oscillations as gyroscopic terms"
        ]
    return ["equilibria of the conservative part (dissipation and forces ignored)"]


def _gyroscopic_effects(mechanics: Mechanics) -> bool:
    """True if the enabled effects act, do no work and have no explicit t: a force
    Q = B(q) qdot + ... with B antisymmetric, which the linearisation keeps."""
    from systems.classification import does_no_work

    forces = mechanics.generalized_forces
    if mechanics.lagrangian is None or all(f == 0 for f in forces):
        return False
    if any(sympy.S(f).has(mechanics.t) for f in forces):
        return False
    return does_no_work(forces, mechanics.qdot)


def _time_dependent_reason(mechanics: Mechanics) -> str:
    """Why a system whose L (or H) contains t gets no equilibria, in words that agree
    with its classification."""
    c = mechanics.classification
    if c.gauge_time:
        return (
            "L contains t only through a total time derivative dF(q, t)/dt, and the "
            "potential of L without it could not be formed, so the equilibria are not "
            "computed"
        )
    # one sentence wherever it is shown: rheonomic is about the constraints, explicit t
    # in L a separate statement; a periodic t leaves constant solutions to Floquet theory
    from systems.textbook.floquet import time_dependence_note

    return time_dependence_note(mechanics)


def _periodic(mechanics, expression, unknowns, searched, parameters) -> tuple[str, ...]:
    """The searched coordinates in which the system is 2 pi-periodic."""
    everything = [*mechanics.q, *mechanics.qdot, *mechanics.p]
    numeric_expression = with_parameters(expression, mechanics, parameters)
    angles = periodic_symbols(numeric_expression, unknowns, everything)
    return tuple(name for name, u in zip(searched, unknowns, strict=True) if u in angles)


def _locate(problem: _Problem, W, symbolic: bool, timeout: float, *, keep_outside: bool, key):
    """The stationary points of ``W`` over ``problem.unknowns``: sympy's (parameters
    symbolic, remembered per derivation under ``key``) and a numeric scan's, each once.

    Returns ``(found, method)``: a list of (point (m,), closed forms by coordinate name)
    and ``"symbolic"``, ``"symbolic+numeric"`` or ``"numeric"``.
    """
    mechanics, unknowns = problem.mechanics, problem.unknowns
    found: list[tuple[np.ndarray, dict[str, str]]] = []
    method = "numeric"
    if (
        symbolic
        and problem.mq <= SYMBOLIC_MAX_COORDINATES
        and len(unknowns) <= SYMBOLIC_MAX_UNKNOWNS
    ):
        # Parameters stay symbolic, so one solve serves every slider position.
        cache = cache_for(mechanics)
        key = (*key, tuple(unknowns))
        if key not in cache:
            cache[key] = _symbolic_solutions(mechanics, W, unknowns, timeout)
        exact = cache[key]
        if exact is not None:
            method = "symbolic"
            coordinates = unknowns[: problem.mq]
            for solution in exact:
                point = problem.evaluate_exact(solution, keep_outside=keep_outside)
                if point is not None:
                    forms = {
                        n: str(solution[s])
                        for n, s in zip(problem.searched, coordinates, strict=True)
                    }
                    found.append((point, forms))
    added = False
    known = [point for point, _ in found]
    for point in problem.scan():
        if problem.index(point, known) < 0:
            found.append((point, {}))
            added = True
    if method == "symbolic" and added:
        method = "symbolic+numeric"
    return _unique(found, problem), method


MAX_CONTACT_SETS = 32
"""At most this many sets of unilateral constraints in contact are tried (fewest first)."""


def _search_constrained(
    mechanics, rows, U, box, parameters, symbolic, timeout
) -> EquilibriumSearch:
    """The equilibria of a scleronomic system with ``[constraints]`` (virtual work with the
    constraint forces): ``dU/dq + A^T lambda = 0`` with A the acting rows.

    Holonomic rows always act. Each set S of unilateral rows is tried in contact
    (g = 0, acting like holonomic ones) with the others free: a point is kept when the
    free ones have g > 0 there and the contacts push (lambda <= 0, the convention of
    ``systems.constraints``). A contact whose force vanishes (grazing) is stable only if
    the point is a minimum without it too. Nonholonomic rows reach here only when U is
    constant (``not_computed``).
    """
    from systems.constraints import multiplier_names

    scene, t = mechanics.scene, mechanics.t
    names = scene.coordinates
    labels = multiplier_names(scene)
    texts = [
        *scene.holonomic_constraints,
        *scene.nonholonomic_constraints,
        *scene.unilateral_constraints,
    ]
    for kind, value, free_part, text in zip(
        rows.kinds, rows.values, rows.time_derivative, texts, strict=True
    ):
        if value.has(t):
            return EquilibriumSearch(
                [],
                "none",
                f"the {kind} constraint {text} moves (it depends explicitly on t), so the "
                "system has no equilibria in these coordinates",
                potential=U,
            )
        if kind == "nonholonomic" and free_part != 0:
            return EquilibriumSearch(
                [],
                "none",
                f"the nonholonomic constraint {text} = 0 has a part without velocities, "
                "which rest cannot satisfy: the system has no equilibria",
                potential=U,
            )
    positional = [i for i, kind in enumerate(rows.kinds) if kind != "nonholonomic"]
    if not U.has(*mechanics.q):
        admissible = "that satisfies the constraints " if positional else ""
        return EquilibriumSearch(
            [],
            "none",
            f"U is constant: every configuration {admissible}is a (neutral) equilibrium at "
            "rest, where the constraints exert no force (\u03bb = 0)",
            free=tuple(names),
            potential=U,
        )
    notes = _effects_notes(mechanics)
    involved = U.free_symbols.union(*(rows.values[i].free_symbols for i in positional))
    free = tuple(name for name, qi in zip(names, mechanics.q, strict=True) if qi not in involved)
    searched = tuple(name for name in names if name not in free)
    if free:
        notes.append(
            f"U and the constraints do not depend on {', '.join(free)}: free (any value), "
            "shown at 0"
        )
    symbol_of = dict(zip(names, mechanics.q, strict=True))
    unknowns = [symbol_of[name] for name in searched]
    expressions = [mechanics.lagrangian, *(rows.values[i] for i in positional)]
    periodic = set(searched)
    for expression in expressions:
        periodic &= set(_periodic(mechanics, expression, unknowns, searched, parameters))
    periodic = tuple(name for name in searched if name in periodic)
    region = _region(searched, periodic, box, scene.view)
    numeric = [with_parameters(rows.values[i], mechanics, parameters) for i in positional]
    U_numeric = with_parameters(U, mechanics, parameters)
    holonomic = [i for i in positional if rows.kinds[i] == "holonomic"]
    unilateral = [i for i in positional if rows.kinds[i] == "unilateral"]
    gaps = vectorize([numeric[positional.index(j)] for j in unilateral] or [0], unknowns)

    sets: list[tuple[int, ...]] = []
    for size in range(min(len(unilateral), len(searched) - len(holonomic)) + 1):
        sets += itertools.combinations(unilateral, size)
    if len(sets) > MAX_CONTACT_SETS:
        sets = sets[:MAX_CONTACT_SETS]
        notes.append(f"only the first {MAX_CONTACT_SETS} sets of contacts were tried")
    problems: dict[tuple[int, ...], _Problem] = {}
    methods, equilibria = [], []
    for contacts in sets:
        acting = [*holonomic, *contacts]
        if acting:
            problem = _ConstrainedProblem(
                mechanics,
                U_numeric,
                [numeric[positional.index(i)] for i in acting],
                [labels[i] for i in acting],
                unknowns,
                searched,
                free,
                periodic,
                region,
                parameters,
            )
            multipliers = problem.unknowns[problem.mq :]
            W = U + sum(
                (lam * rows.values[i] for lam, i in zip(multipliers, acting, strict=True)),
                sympy.S.Zero,
            )
            key = ("equilibria.constrained", tuple(acting))
        else:
            problem = _Problem(
                mechanics, U_numeric, unknowns, searched, free, periodic, region, parameters
            )
            W, key = U, ("equilibria.symbolic",)
        problems[contacts] = problem
        found, method = _locate(problem, W, symbolic, timeout, keep_outside=box is None, key=key)
        methods.append(method)
        for equilibrium in problem.classify(found):
            kept = _admissible(equilibrium, problem, contacts, unilateral, gaps, searched)
            if kept is not None:
                kept = _with_contacts(kept, contacts, labels, problems, searched)
            if kept is not None:
                equilibria.append(kept)
    equilibria.sort(key=lambda e: (round(e.potential, 9), tuple(e.q.values())))
    if not equilibria:
        notes.insert(
            0,
            "dU/dq is balanced by no admissible constraint force in the search box"
            if unilateral
            else "dU/dq is balanced by no constraint force in the search box",
        )
    if "numeric" in methods:
        method = "symbolic+numeric" if any(m.startswith("symbolic") for m in methods) else "numeric"
    else:
        method = "symbolic+numeric" if "symbolic+numeric" in methods else "symbolic"
    return EquilibriumSearch(
        equilibria,
        method,
        "; ".join(notes),
        searched=searched,
        free=free,
        periodic=periodic,
        box=region,
        potential=U,
        multipliers=tuple(labels),
    )


def _gap_tolerance(problem: _Problem) -> float:
    widths = [hi - lo for lo, hi in problem.region.values()]
    return 1e-9 * max(1.0, float(np.mean(widths)))


def _admissible(equilibrium, problem, contacts, unilateral, gaps, searched):
    """``equilibrium`` if the unilateral constraints out of contact have g > 0 there, else
    None; of a set, the points where they do not are dropped (and the point shown is
    moved into what remains)."""
    if not unilateral:
        return equilibrium
    tol = _gap_tolerance(problem)
    loose = [unilateral.index(j) for j in unilateral if j not in contacts]
    if not loose:
        return equilibrium

    def admissible(points):  # (k, m) searched coordinates
        values = np.asarray(gaps(*points.T), dtype=float).reshape(len(unilateral), len(points))
        return np.all(values[loose] > tol, axis=0)

    point = np.array([[equilibrium.q[name] for name in searched]])
    if equilibrium.continuum is None:
        return equilibrium if bool(admissible(point)[0]) else None
    index_r = [problem.names.index(name) for name in searched]
    every = equilibrium.continuum.points
    keep = admissible(every[:, index_r])
    if not np.any(keep):
        return None
    continuum = replace(
        equilibrium.continuum,
        points=every[keep],
        momenta=equilibrium.continuum.momenta[keep],
        closed=bool(equilibrium.continuum.closed and np.all(keep)),
    )
    equilibrium = replace(equilibrium, continuum=continuum)
    if bool(admissible(point)[0]):
        return equilibrium
    x = every[keep][0, index_r]  # the point shown was outside: one inside instead
    if isinstance(problem, _ConstrainedProblem):
        x = problem.complete(x)
    moved, _ = problem.equilibrium(x, {})
    return replace(
        moved, kind=equilibrium.kind, decided_by=equilibrium.decided_by, continuum=continuum
    )


def _with_contacts(equilibrium, contacts, labels, problems, searched) -> Equilibrium | None:
    """Every multiplier (0 out of contact), the contacts, and what they decide; None where
    a contact pulls (lambda > 0: the system would leave it). A contact that pushes with no
    force (grazing) leaves the stability to the analysis without it."""
    values = dict.fromkeys(labels, 0.0)
    values.update(equilibrium.multipliers)
    names = tuple(labels[i] for i in contacts)
    equilibrium = replace(equilibrium, multipliers=values, contacts=names)
    if not contacts:
        return equilibrium
    problem = problems[contacts]
    scale = problem.gradient_scale
    pushes = [values[name] <= 1e-9 * scale for name in names]
    if not all(pushes):  # a set is judged by its representative point; it is not split
        return None
    grazing = [name for name in names if abs(values[name]) <= 1e-9 * scale]
    forces = ", ".join(f"{_greek(name)} = {_short(values[name])}" for name in names)
    if not grazing:
        text = (
            f"in contact, the constraint pushing ({forces} \u2264 0): leaving the contact "
            "raises U at first order"
        )
        return replace(equilibrium, decided_by=f"{equilibrium.decided_by}; {text}")
    rest = tuple(i for i, name in zip(contacts, names, strict=True) if name not in grazing)
    relaxed = problems.get(rest)
    stable = False
    if relaxed is not None:
        x = np.array([equilibrium.q[name] for name in searched])
        if isinstance(relaxed, _ConstrainedProblem):
            x = relaxed.complete(x)
        free_analysis, _ = relaxed.equilibrium(x, {})
        stable = free_analysis.verdict in ("stable: minimum", "stable: fixed")
    which = ", ".join(_greek(name) for name in grazing)
    if stable:
        text = (
            f"the contact force vanishes ({which} = 0, grazing); U has a strict minimum "
            "without that contact too: stable, but the motion meets the wall, so it is "
            "not a harmonic oscillation"
        )
        return replace(
            equilibrium, stable=True, frequencies=[], verdict="stable: grazing", decided_by=text
        )
    text = (
        f"the contact force vanishes ({which} = 0, grazing) and U has no strict minimum "
        "without that contact: not known to be stable"
    )
    return replace(
        equilibrium,
        stable=False,
        frequencies=[],
        kind="degenerate" if equilibrium.kind != "continuum" else "continuum",
        verdict="undecided",
        decided_by=text,
    )


def _greek(label: str) -> str:
    """``lambda_2`` -> ``λ₂``."""
    number = label.rsplit("_", 1)[-1]
    return "\u03bb" + number.translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))


# -- the pieces -------------------------------------------------------------------------------


def _region(searched, periodic, box: Box | None, view: Mapping) -> dict[str, tuple[float, float]]:
    ranges = view.get("ranges", {}) if isinstance(view, Mapping) else {}
    region = {}
    for name in searched:
        if box is not None and name in box:
            lo, hi = (float(v) for v in box[name])
            if not lo < hi:
                raise ValueError(f"the box of {name!r} is empty: ({lo}, {hi})")
        elif name in periodic:
            lo, hi = -math.pi, math.pi
        else:
            lo, hi = -DEFAULT_HALF_WIDTH, DEFAULT_HALF_WIDTH
            try:  # a scene's view range, widened three times about its centre
                a, b = (float(v) for v in ranges[name])
                centre, width = (a + b) / 2, abs(b - a)
                lo, hi = min(lo, centre - 1.5 * width), max(hi, centre + 1.5 * width)
            except (KeyError, TypeError, ValueError):
                pass
        region[name] = (lo, hi)
    return region


def _symbolic_solutions(mechanics: Mechanics, U, unknowns, timeout: float):
    """sympy's solutions of dU/dq = 0 (dicts symbol -> expression), or None."""
    # Positive parameters as positive symbols, so that sqrt and acos come out simply.
    values = mechanics.scene.parameter_values
    positive = {
        s: sympy.Symbol(name, positive=True)
        for name, s in mechanics.params.items()
        if values.get(name, 0.0) > 0
    }
    gradient = [sympy.diff(U.xreplace(positive), u) for u in unknowns]
    if sum(g.count_ops() for g in gradient) > SYMBOLIC_MAX_OPS:
        return None
    solutions = run_bounded(_solve, (gradient, unknowns), timeout)
    if solutions is None:
        return None
    back = {v: k for k, v in positive.items()}
    return [{k: v.xreplace(back) for k, v in s.items()} for s in solutions]


def _solve(gradient, unknowns):
    """Runs in the child process. One unknown: solve each factor of dU/dq on its own
    (faster, and sympy then finds both sin = 0 roots); several: ``sympy.solve``."""
    if len(unknowns) == 1:
        (u,) = unknowns
        numerator, _ = sympy.fraction(sympy.together(gradient[0]))
        try:
            factors = [f for f, _ in sympy.factor_list(numerator)[1] if f.has(u)]
        except sympy.PolynomialError:
            factors = [numerator]
        return [{u: value} for factor in factors for value in sympy.solve(factor, u)]
    solutions = sympy.solve(gradient, unknowns, dict=True)
    complete = [s for s in solutions if all(u in s for u in unknowns)]
    if len(complete) != len(solutions):  # a continuum of equilibria: leave it to numerics
        return None
    return complete


class _Problem:
    """dU/dq = 0 over the searched coordinates, with numbers for the parameters.

    ``unknowns`` are the searched coordinates' symbols, then (``_ConstrainedProblem``)
    the multipliers; ``mq`` counts the coordinates among them.
    """

    def __init__(self, mechanics, U, unknowns, searched, free, periodic, region, parameters):
        self.mechanics = mechanics
        self.names = mechanics.scene.coordinates
        self.searched, self.free, self.periodic = searched, free, periodic
        self.region = region
        self.parameters = parameters
        self.unknowns = unknowns
        m = len(unknowns)
        self.mq = len(searched)
        self.is_periodic = np.array(
            [name in periodic for name in searched] + [False] * (m - self.mq), dtype=bool
        )
        gradient, hessian = _derivatives(mechanics, U, unknowns)
        self.blocks = _blocks([h != 0 for h in hessian], m)
        self.gradient = vectorize(gradient, unknowns)
        self._hessian = vectorize(hessian, unknowns)
        self.U = vectorize([U], unknowns)
        self.m = m
        grid = self.starts()
        with np.errstate(all="ignore"):
            g = np.linalg.norm(self.gradient(*grid.T), axis=0)
            h = np.abs(self._hessian(*grid.T))
        self.gradient_scale = _typical(g)
        self.hessian_scale = _typical(h)
        self.mass = _mass_function(mechanics, parameters)
        zero = {**dict.fromkeys(mechanics.qdot, 0), mechanics.t: 0}
        # zero velocities first: what is left (often 0) is smaller to give numbers to
        if mechanics.matrix_form is not None:  # a = p at zero velocity, already formed
            momenta = [
                with_parameters(e.xreplace(zero), mechanics, parameters)
                for e in mechanics.matrix_form.shift
            ]
        elif mechanics.momenta is not None:
            momenta = [
                with_parameters(e.xreplace(zero), mechanics, parameters) for e in mechanics.momenta
            ]
        else:
            momenta = [sympy.S.Zero] * len(self.names)
        momenta_function = vectorize(momenta, mechanics.q)
        self.rest_momenta = lambda q: momenta_function(*q)
        self.cross = _cross_function(mechanics, momenta, parameters)
        widths = [hi - lo for lo, hi in region.values()]
        # lengths for following U along degenerate directions and along sets of equilibria
        self.probe_length = 0.005 * float(np.mean(widths))
        self.trace_step = 0.005 * float(np.mean(widths))
        self.equation = None  # set by the search: f(q) = 0 of a continuum, from sympy
        # a length per searched coordinate, for probing about chart singularities
        self.scales = np.array(
            [1.0 if name in periodic else (region[name][1] - region[name][0]) / (2 * math.pi)
             for name in searched]
        )  # fmt: skip
        self._embedded = None  # (position function or None,), built when first needed

    def hessian(self, x: np.ndarray) -> np.ndarray:
        return self._hessian(*x).reshape(self.m, self.m)

    def starts(self) -> np.ndarray:
        """Starting points, shape (s, m): a grid for m <= 3, a Halton set beyond."""
        m = self.mq
        lows = np.array([self.region[n][0] for n in self.searched])
        highs = np.array([self.region[n][1] for n in self.searched])
        return lows + (highs - lows) * _unit_starts(m)

    def scan(self) -> list[np.ndarray]:
        """The stationary points the root finder reaches from ``starts``.

        Where dU/dq splits into independent blocks of coordinates (U a sum of terms in
        disjoint sets of coordinates: a chain whose V is a sum over its links), each
        block is solved alone from its own low-dimensional starts and the equilibria are
        every combination of the blocks' roots, all of them: a six-link chain's 64 from
        6 scans of 41 starts instead of a scan of 400 starts in six dimensions.
        """
        blocks = self.blocks
        if len(blocks) > 1 and self.m == self.mq:
            roots = [self._block_roots(block) for block in blocks]
            if math.prod(len(r) for r in roots) <= MAX_COMBINED_ROOTS:
                return self._combined(blocks, roots)
        everything = list(range(self.m))
        # with multipliers among the unknowns (constraints) there is no region to bound
        # Newton's steps by: scipy's hybrid method from every start, as before
        return self._roots(everything, self.starts(), np.zeros(self.m), newton=self.m == self.mq)

    def _block_roots(self, block: list[int]) -> list[np.ndarray]:
        """The roots of dU/dq over the coordinates ``block`` (the others at the middle
        of their range: the block's gradient does not depend on them), each polished."""
        lows = np.array([self.region[self.searched[i]][0] for i in block])
        highs = np.array([self.region[self.searched[i]][1] for i in block])
        base = np.array([sum(self.region[name]) / 2 for name in self.searched])
        starts = lows + (highs - lows) * _unit_starts(len(block))
        return [x[block] for x in self._roots(block, starts, base)]

    def _roots(self, block, starts, base, *, newton: bool = True) -> list[np.ndarray]:
        """The roots of dU/dq over the unknowns ``block`` reached from ``starts`` (the
        other unknowns at ``base``), in the order of the starts, each accepted, polished
        and kept once.

        Newton's method runs from every start at once (``_newton``); a start it does not
        bring to a root in the region goes to scipy's hybrid method, as every start did
        before: a six-link chain's search made 246 calls to it (and imported scipy, a
        quarter of a second) for 12 roots. Only the first start that reaches a root is
        polished.
        """

        def full(y):
            x = base.copy()
            x[block] = y
            return x

        if newton:
            ranges = [self.region[self.searched[i]] for i in block]
            ends, reached = self._newton(base, block, starts, np.array([b - a for a, b in ranges]))
        else:
            ends, reached = np.zeros((len(starts), self.m)), np.zeros(len(starts), dtype=bool)
        found: list[np.ndarray] = []
        seen: list[np.ndarray] = []  # Newton's roots so far: most starts end at a few
        for y0, end, ok in zip(starts, ends, reached, strict=True):
            x = self.accept(end, inside_only=True, block=block) if ok else None
            if x is not None:
                if self.index(x, seen) >= 0:
                    continue
                seen.append(x)
            else:
                x = self.accept(self._hybrid(full, block, y0), inside_only=True, block=block)
            if x is not None:
                x = self.accept(self.polish(x, block=block), inside_only=True, block=block)
            if x is not None and self.index(x, found) < 0:
                found.append(x)
        return found

    def _newton(self, base, block, starts, widths) -> tuple[np.ndarray, np.ndarray]:
        """Newton's method on dU/dq over ``block`` from every start at once.

        Returns the end points, shape (s, m), and which of them are roots (dU/dq there
        within ``accept``'s tolerance). A step is at most a tenth of the region's width
        along each coordinate (a start where the Hessian nearly vanishes would jump
        out of it); a singular Hessian takes the least-squares step.
        """
        x = np.tile(base, (len(starts), 1))
        x[:, block] = starts
        periodic = self.is_periodic[block]
        limit = 0.1 * widths
        index = np.ix_(block, block)
        with np.errstate(all="ignore"):
            for _ in range(NEWTON_ITERATIONS):
                g = self.gradient(*x.T)[block].T
                K = self._hessian(*x.T).reshape(self.m, self.m, -1)[index].transpose(2, 0, 1)
                bad = ~(np.all(np.isfinite(g), axis=1) & np.all(np.isfinite(K), axis=(1, 2)))
                g[bad], K[bad] = 0.0, np.eye(len(block))
                try:
                    step = np.linalg.solve(K, g[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    step = (np.linalg.pinv(K) @ g[..., None])[..., 0]
                step *= np.minimum(1.0, np.min(limit / np.maximum(np.abs(step), 1e-300), axis=1))[
                    :, None
                ]
                y = x[:, block] - step
                x[:, block] = np.where(periodic, fold_angle(y), y)
                if np.all(np.abs(step) <= 1e-15 * (1.0 + np.abs(y))):
                    break
            residual = np.linalg.norm(self.gradient(*x.T)[block], axis=0)
        reached = np.isfinite(residual) & (residual <= 1e-7 * self.gradient_scale)
        return x, reached & np.all(np.isfinite(x), axis=1)

    def _hybrid(self, full, block, y0) -> np.ndarray:
        """scipy's hybrid method on dU/dq over ``block`` from ``y0`` (NaN if it fails)."""
        import scipy.optimize

        index = np.ix_(block, block)
        with np.errstate(all="ignore"):
            try:
                sol = scipy.optimize.root(
                    lambda y: self.gradient(*full(y))[block],
                    y0,
                    jac=lambda y: self.hessian(full(y))[index],
                    method="hybr",
                    options={"xtol": 1e-13},
                )
            except (ValueError, np.linalg.LinAlgError, FloatingPointError):
                return np.full(len(full(y0)), np.nan)
        return full(sol.x)

    def _combined(self, blocks, roots) -> list[np.ndarray]:
        """Every combination of the blocks' roots that is an equilibrium."""
        found: list[np.ndarray] = []
        for combination in itertools.product(*roots):
            x = np.zeros(self.m)
            for block, values in zip(blocks, combination, strict=True):
                x[block] = values
            x = self.accept(x, inside_only=True)
            if x is not None:
                found.append(x)
        return found

    def polish(self, x: np.ndarray, iterations: int = 100, block=None) -> np.ndarray:
        """Newton steps (least squares where K is singular) from a root finder's answer,
        over the coordinates ``block`` (default all).

        At a degenerate equilibrium (U = x^4 + ...) the root finder stops where dU/dq is
        merely small, up to 1e-2 away, and each start would add its own "equilibrium";
        Newton converges there too, linearly, to the one point.
        """
        block = slice(None) if block is None else block
        index = np.ix_(np.arange(self.m)[block], np.arange(self.m)[block])
        start = x = np.asarray(x, dtype=float)
        singular = np.linalg.svd(self.hessian(x)[index], compute_uv=False)
        if singular[-1] > 1e-3 * singular[0]:
            return x  # a regular root: the root finder's answer is as good as Newton's
        smallest, stalled = math.inf, 0
        with np.errstate(all="ignore"):
            for _ in range(iterations):
                g, K = self.gradient(*x)[block], self.hessian(x)[index]
                if not (np.all(np.isfinite(g)) and np.all(np.isfinite(K))):
                    return start
                try:
                    step = np.linalg.lstsq(K, g, rcond=None)[0]
                except np.linalg.LinAlgError:
                    return start
                size = float(np.linalg.norm(step))
                stalled = stalled + 1 if size > 0.95 * smallest else 0
                if stalled >= 5:  # rounding noise, not convergence
                    break
                x, smallest = x.copy(), min(smallest, size)
                x[block] -= step
                if not np.all(np.isfinite(x)) or np.linalg.norm(x - start) > self.probe_length:
                    return start  # not converging to a point near this one
                if size <= 1e-15 * (1.0 + np.linalg.norm(x)):
                    break
        return x

    def accept(self, x: np.ndarray, *, inside_only: bool, block=None) -> np.ndarray | None:
        """``x`` with its angles folded if dU/dq vanishes there (over the coordinates
        ``block``, default all) and, with ``inside_only``, it lies in the region."""
        x = np.asarray(x, dtype=float)
        if not np.all(np.isfinite(x)):
            return None
        x = np.where(self.is_periodic, fold_angle(x), x)
        x[: self.mq] = self._zeroed(x[: self.mq])
        block = slice(None) if block is None else block
        with np.errstate(all="ignore"):
            residual = float(np.linalg.norm(self.gradient(*x)[block]))
        if not np.isfinite(residual) or residual > 1e-7 * self.gradient_scale:
            return None
        if inside_only:
            coordinates = zip(x[: self.mq], self.searched, self.is_periodic, strict=False)
            for value, name, periodic in coordinates:
                lo, hi = self.region[name]
                margin = 1e-9 * (hi - lo)
                if not periodic and not lo - margin <= value <= hi + margin:
                    return None
                if periodic and not lo - margin <= value <= hi + margin:
                    return None
        return x

    def _zeroed(self, q: np.ndarray) -> np.ndarray:
        """``q`` (searched coordinates, shape (mq,)) with the coordinates that are zero to
        round-off set to 0: Newton ends a few ulps of the largest coordinate or of the
        searched range away from an exact 0 (fpu_chain printed q11 = -1.7e-15)."""
        ranges = (self.region[name] for name in self.searched)
        widths = [w for lo, hi in ranges if math.isfinite(w := hi - lo)]
        scale = max(float(np.max(np.abs(q), initial=0.0)), *widths, 0.0)
        return np.where(np.abs(q) <= 64 * np.finfo(float).eps * scale, 0.0, q)

    def evaluate_exact(self, solution: dict, *, keep_outside: bool) -> np.ndarray | None:
        values = parameter_values(self.mechanics, self.parameters)
        point = []
        for u in self.unknowns:
            try:
                value = complex(sympy.N(solution[u].xreplace(values), 17))
            except (TypeError, ValueError, ZeroDivisionError):
                return None
            if abs(value.imag) > 1e-10 * max(1.0, abs(value.real)):
                return None
            point.append(value.real)
        return self.accept(np.array(point), inside_only=not keep_outside)

    def same(self, a: np.ndarray, b: np.ndarray) -> bool:
        """The same configuration (the multipliers follow from it)."""
        a, b, periodic = a[: self.mq], b[: self.mq], self.is_periodic[: self.mq]
        d = np.abs(a - b)
        d = np.where(periodic, np.minimum(d, 2 * math.pi - d), d)
        return bool(np.all(d <= 1e-6 * (1.0 + np.abs(a))))

    def index(self, a: np.ndarray, points) -> int:
        """The first ``i`` with ``same(a, points[i])``, or -1; one array operation (a
        chain of ten links has hundreds of equilibria, and pairwise calls cost seconds)."""
        if len(points) == 0:
            return -1
        a = a[: self.mq]
        d = np.abs(np.asarray(points, dtype=float).reshape(len(points), -1)[:, : self.mq] - a)
        d = np.where(self.is_periodic[: self.mq], np.minimum(d, 2 * math.pi - d), d)
        hits = np.flatnonzero(np.all(d <= 1e-6 * (1.0 + np.abs(a)), axis=1))
        return int(hits[0]) if hits.size else -1

    def equilibrium(self, x: np.ndarray, exact: dict[str, str]) -> tuple[Equilibrium, int]:
        """The equilibrium at ``x`` (searched coordinates, then any multipliers, shape
        (m,)), and the number of degenerate directions along which U is flat (0 unless it
        may lie on a set). With constraints K, M and G are those of the tangent space."""
        n, mq = len(self.names), self.mq
        full = dict.fromkeys(self.names, 0.0)
        full.update({name: float(v) for name, v in zip(self.searched, x[:mq], strict=True)})
        q = np.array([full[name] for name in self.names])
        M = self.mass(q)
        if self.chart_singular(M):
            return self._singular(x, q, M, exact), 0
        K = self.hessian(x)[:mq, :mq]
        K = (K + K.T) / 2
        index_r = [self.names.index(name) for name in self.searched]
        index_f = [self.names.index(name) for name in self.free]
        Mrr = M[np.ix_(index_r, index_r)]
        back = np.zeros((len(index_f), mq))
        if index_f:
            Mff = M[np.ix_(index_f, index_f)]
            Mfr = M[np.ix_(index_f, index_r)]
            back = -np.linalg.pinv(Mff) @ Mfr  # pinv: M_ff may vanish (spherical pendulum)
            Mrr = Mrr + Mfr.T @ back
        G, hamiltonian = self.cross.gyroscopic(q, index_r, index_f, back)
        basis = self.tangent(x)  # the searched coordinates' motions that keep the constraints
        K, Mrr = basis.T @ K @ basis, basis.T @ Mrr @ basis
        if G is not None and basis.shape[1] < mq:
            reduced = basis.T @ G @ basis  # what the constraints let act
            big = float(np.max(np.abs(G)))
            G = reduced if float(np.max(np.abs(reduced), initial=0.0)) > 1e-10 * big else None
        m = len(K)
        regular = _regular(Mrr) if m else True  # m = 0: the constraints fix every coordinate
        H_qq = K
        if hamiltonian and G is not None and regular:
            # U at rest is H minimized over p: H_qq - H_qp H_pp^-1 H_pq, as for a Lagrangian
            K = H_qq - G @ Mrr @ G.T
        eig_K, vec_K = np.linalg.eigh(K)
        tol = 1e-8 * max(self.hessian_scale, float(np.max(np.abs(eig_K), initial=0.0)), 1e-300)
        null = np.abs(eig_K) <= tol
        if np.any(null):
            kind = "degenerate"
            # the numerically zero eigenvalues set to zero, so that a degenerate direction
            # gives zero eigenvalues, not the square roots of rounding errors
            K = (vec_K * np.where(null, 0.0, eig_K)) @ vec_K.T
        elif np.all(eig_K > 0):
            kind = "minimum"
        elif np.all(eig_K < 0):
            kind = "maximum"
        else:
            kind = "saddle"
        if m == 0:
            w2, vectors = np.zeros(0), np.zeros((0, 0))
        elif regular:
            try:
                w2, vectors = _generalized_eigh(K, Mrr)
            except (np.linalg.LinAlgError, ValueError):
                import scipy.linalg

                w2, vectors = scipy.linalg.eig(K, Mrr)
                order = np.argsort(w2.real)
                w2, vectors = w2.real[order], vectors.real[:, order]
        else:  # no inertia, or infinite: no small oscillations (H = p**4/4 at p = 0, m = 0)
            w2, vectors = np.full(m, np.nan), np.zeros((m, m))
        modes = np.zeros((n, m))
        modes[index_r] = basis @ vectors
        if index_f:
            modes[index_f] = back @ basis @ vectors
        finite = np.abs(w2[np.isfinite(w2)])
        w2_tol = 1e-8 * max(float(finite.max()) if finite.size else 0.0, 1e-300)
        gyroscopic = G is not None and regular
        if gyroscopic:
            if hamiltonian:  # Hess H = [[H_qq, H_qp], [H_pq, H_pp]], H_pp = M^-1
                eigenvalues, shapes = _spectrum(H_qq, np.linalg.inv(Mrr), G, True)
            else:
                eigenvalues, shapes = _spectrum(K, Mrr, G, False)
        elif regular:
            root = np.sqrt(np.abs(w2).astype(complex))
            growth = np.where(w2 < -w2_tol, root.real, 0.0)
            turn = np.where(w2 > w2_tol, root.real, 0.0)
            eigenvalues = np.concatenate([growth + 1j * turn, -growth - 1j * turn])
            eigenvalues = eigenvalues[np.argsort(eigenvalues.imag, kind="stable")]
        else:
            eigenvalues = np.zeros(0, dtype=complex)
        scale = max(float(np.max(np.abs(eigenvalues), initial=0.0)), 1e-300)
        if gyroscopic:
            growing = bool(np.any(eigenvalues.real > 1e-7 * scale))
        else:
            growing = bool(np.any(eig_K < -tol))
        verdict, order, flat = self._decide(
            x, kind, eig_K, basis @ vec_K, null, growing, G is not None
        )
        stable = verdict.startswith("stable")
        frequencies: list[float] = []
        if stable and regular:
            if gyroscopic:
                turns = np.sort(np.abs(eigenvalues.imag))
                turns = turns[turns > 1e-7 * scale]
                frequencies = [float(w) for w in turns[::2]]
                keep = np.flatnonzero(eigenvalues.imag > 1e-7 * scale)
                keep = keep[np.argsort(eigenvalues.imag[keep])]
                modes = np.zeros((n, len(keep)), dtype=complex)
                modes[index_r] = basis @ shapes[:, keep]
                if index_f:
                    modes[index_f] = back @ basis @ shapes[:, keep]
            else:
                frequencies = [float(math.sqrt(v)) for v in w2 if v > w2_tol]
        decided_by = _decided_text(verdict, kind, eig_K, null, order, regular, G is not None)
        return (
            Equilibrium(
                q=full,
                stable=stable,
                kind=kind,
                frequencies=frequencies,
                omega_squared=np.asarray(w2, dtype=float),
                modes=modes,
                hessian=K,
                potential=float(self.U(*x)[0]),
                p={
                    f"p_{name}": _clean(v)
                    for name, v in zip(self.names, self.rest_momenta(q), strict=True)
                },
                exact=exact,
                eigenvalues=eigenvalues,
                gyroscopic=np.zeros((m, m)) if G is None else G,
                order=order,
                decided_by=decided_by,
                verdict=verdict,
            ),
            flat,
        )

    def tangent(self, x: np.ndarray) -> np.ndarray:
        """An orthonormal basis (mq, d) of the searched coordinates' displacements that
        keep the constraints at ``x``: all of them without constraints."""
        return np.eye(self.mq)

    # -- chart singularities -----------------------------------------------------------

    def full(self, x: np.ndarray) -> np.ndarray:
        """All n coordinates at the searched point ``x`` (free ones at 0)."""
        q = np.zeros(len(self.names))
        q[[self.names.index(name) for name in self.searched]] = x[: self.mq]
        return q

    def chart_singular(self, M: np.ndarray) -> bool:
        """True where the mass matrix of a Lagrangian is finite and singular: the
        coordinates fail there (a Hamiltonian whose kinetic term has no inverse at p = 0,
        as p**4/4, is no chart singularity: there are no small oscillations)."""
        if self.mechanics.lagrangian is None or not np.all(np.isfinite(M)):
            return False
        return not _regular(M)

    def conditioning(self, x: np.ndarray) -> float:
        """The smallest singular value of M over its largest at ``x`` (0 where singular)."""
        M = self.mass(self.full(x))
        if not np.all(np.isfinite(M)):
            return 0.0
        singular = np.linalg.svd(M, compute_uv=False)
        return float(singular[-1] / singular[0]) if singular[0] > 0 else 0.0

    def position(self):
        """The particles' mass-weighted positions as a function of q (``charts.embedding``),
        None where the scene has no fixed particles or L has velocity-linear terms."""
        if self._embedded is None:
            from systems.textbook import charts

            plain = self.cross.function is None and self.cross.effects is None
            plain = plain and self.m == self.mq  # no constraints
            f = charts.embedding(self.mechanics, self.parameters) if plain else None
            self._embedded = (f,)
        return self._embedded[0]

    def _singular(self, x, q, M, exact) -> Equilibrium:
        """The equilibrium at a chart singularity: decided in the regular local chart of
        the particles' positions (``charts.local_chart``), or undecided with the reason."""
        from systems.textbook import charts

        # the coordinates that the singular directions of M leave alone are what is fixed
        _, values, vectors = np.linalg.svd(M)
        kernel = vectors[values <= 1e-13 * max(float(values[0]), 1e-300)]
        moving = np.any(np.abs(kernel) > 1e-8, axis=0)
        named = [
            f"{name} = {_short(v)}"
            for name, v, moves in zip(self.names, q, moving, strict=True)
            if name in self.searched and not moves
        ] or [
            f"{name} = {_short(full_value)}"
            for name, full_value in zip(self.names, q, strict=True)
            if name in self.searched
        ]
        chart = f"chart singularity at {', '.join(named)}: the mass matrix is singular there"
        potential = float(self.U(*x)[0])
        rest = {
            f"p_{name}": _clean(v) for name, v in zip(self.names, self.rest_momenta(q), strict=True)
        }
        common = dict(
            q=dict(zip(self.names, map(float, q), strict=True)),
            modes=np.zeros((len(self.names), 0)),
            potential=potential,
            p=rest,
            exact=exact,
            chart=chart,
        )
        if self.m != self.mq:
            return self._undecided_at_singularity(
                common, "with constraints no regular chart is formed"
            )
        if self.cross.function is not None or self.cross.effects is not None:
            return self._undecided_at_singularity(
                common, "its velocity-linear terms are not carried into a regular chart"
            )
        n, index_r = len(self.names), [self.names.index(name) for name in self.searched]
        scales = np.ones(n)
        scales[index_r] = self.scales
        position = self.position()
        if position is not None:
            local = charts.local_chart(
                position, lambda point: float(self.U(*point[index_r])[0]), q, scales
            )
            if local.reason:
                return self._undecided_at_singularity(common, local.reason)
            stiffness = local.stiffness
            how = "in a regular local chart (the particles' positions on the tangent plane)"
        else:

            def gradient(point):
                g = np.zeros(n)
                g[index_r] = self.gradient(*point[index_r])
                return g

            def hessian(point):
                K = np.zeros((n, n))
                K[np.ix_(index_r, index_r)] = self.hessian(point[index_r])
                return K

            w2, reason = charts.covariant_limit(
                self.mass, self._mass_derivatives(), gradient, hessian, q, scales
            )
            if reason:
                return self._undecided_at_singularity(common, reason)
            stiffness = np.diag(w2)
            how = (
                "as the limit from the regular points around it (M\u207b\u00b9 times the "
                "covariant Hessian of U, the same in every chart)"
            )
        w2 = np.linalg.eigvalsh(stiffness)
        tol = 1e-6 * max(float(np.max(np.abs(w2))), 1e-300)
        zero = np.abs(w2) <= tol
        growth = np.sqrt(np.where(w2 < -tol, -w2, 0.0))
        turn = np.sqrt(np.where(w2 > tol, w2, 0.0))
        eigenvalues = np.concatenate([growth + 1j * turn, -growth - 1j * turn])
        eigenvalues = eigenvalues[np.argsort(eigenvalues.imag, kind="stable")]
        # the coordinates U does not depend on move the system where the chart is singular
        # too, less the directions that move nothing (the kernel of M): along those U is
        # constant, a neutral direction, as a free coordinate is at a regular point
        fibre = int(np.count_nonzero(np.linalg.svd(M, compute_uv=False) <= 1e-13 * np.abs(M).max()))
        neutral = max(len(self.free) - fibre, 0)
        zeros = int(np.count_nonzero(zero))
        along = ", neutral along the free coordinates" if zeros else ""
        if zeros <= neutral and np.all(w2[~zero] > tol):
            kind, verdict, stable = "minimum", "stable: minimum", True
            decided = f"{chart}; {how} U has a strict minimum{along}"
        elif zeros <= neutral and np.all(w2[~zero] < -tol):
            kind, verdict, stable = "maximum", "unstable: linear", False
            decided = f"{chart}; {how} U has a maximum{along}: a growing mode"
        elif np.any(w2 < -tol):
            verdict, stable, kind = "unstable: linear", False, "saddle"
            decided = f"{chart}; {how} U has a saddle: a growing mode"
        else:
            kind, verdict, stable = "degenerate", "undecided", False
            decided = f"{chart}; {how} K has {_zeros(zeros)} and a minimum across: not decided"
        return Equilibrium(
            stable=stable,
            kind=kind,
            frequencies=[float(w) for w in np.sort(turn[w2 > tol])] if stable else [],
            omega_squared=w2,
            hessian=stiffness,
            eigenvalues=eigenvalues,
            gyroscopic=np.zeros_like(stiffness),
            decided_by=decided,
            verdict=verdict,
            **common,
        )

    def _mass_derivatives(self):
        """dM/dq as ``f(q (n,)) -> (n, n, n)``, ``[k, i, j] = dM_ij/dq_k`` (at rest)."""
        mechanics, n = self.mechanics, len(self.names)
        zero = {**dict.fromkeys(mechanics.qdot, 0), mechanics.t: 0}
        M = [
            with_parameters(e, mechanics, self.parameters).xreplace(zero)
            for e in mechanics.mass_matrix
        ]
        entries = [sympy.diff(e, qk) for qk in mechanics.q for e in M]
        f = vectorize(entries, mechanics.q)
        return lambda q: np.asarray(f(*q), dtype=float).reshape(n, n, n)

    def _undecided_at_singularity(self, common: dict, reason: str) -> Equilibrium:
        return Equilibrium(
            stable=False,
            kind="degenerate",
            frequencies=[],
            omega_squared=np.zeros(0),
            hessian=np.zeros((0, 0)),
            decided_by=f"{common['chart']}, so the coordinates cannot decide stability ({reason})",
            verdict="undecided",
            **common,
        )

    # -- stability beyond the linearisation ---------------------------------------------

    def _decide(self, x, kind, eig_K, vec_K, null, growing, gyroscopic):
        """``(verdict, order, flat)``: the verdict a key of ``_VERDICTS``, the order of U
        along degenerate directions, the number of those along which U is flat."""
        if not np.any(null):
            if growing:
                return "unstable: linear", None, 0
            if kind == "minimum":
                return "stable: minimum", None, 0
            return ("stable: gyroscopic", None, 0) if gyroscopic else ("unstable: linear", None, 0)
        transverse_minimum = bool(np.all(eig_K[~null] > 0))
        # followed even when a mode grows, so that an unstable set is recognised as one
        shape, order = self._along_degenerate(x, vec_K, null)
        if shape == "flat":
            flat = int(np.count_nonzero(null))
            if transverse_minimum:
                return "stable: flat", None, flat
            if gyroscopic and not growing:
                return "stable: flat gyroscopic", None, flat
            return "unstable: flat", None, flat
        if growing:
            return "unstable: linear", None, 0
        if shape in ("falls", "odd"):
            return f"unstable: {shape}", order, 0
        if shape == "rises" and transverse_minimum:
            return "stable: rises", order, 0
        return "undecided", order, 0

    def _along_degenerate(self, x, vec_K, null) -> tuple[str, int | None]:
        """How U behaves along the null space of K at ``x``: ``"rises"`` (every way),
        ``"falls"``, ``"odd"`` (rises one way and falls the other), ``"flat"`` or
        ``"mixed"``; and the order of its leading term (None if flat or unclear)."""
        N, R = vec_K[:, null], vec_K[:, ~null]
        d = N.shape[1]
        if d == 1:
            directions = [N[:, 0], -N[:, 0]]
        elif d == 2:
            angles = np.linspace(0.0, 2 * math.pi, 12, endpoint=False)
            directions = [N @ np.array([math.cos(a), math.sin(a)]) for a in angles]
        else:
            rng = np.random.default_rng(5)
            units = np.vstack([np.eye(d), -np.eye(d), rng.normal(size=(4 * d, d))])
            directions = [N @ (u / np.linalg.norm(u)) for u in units]
        steps = self.probe_length * 2.0 ** -np.arange(6)
        noise = 1e-11 * self.gradient_scale
        shapes, orders = [], []
        for v in directions:
            slopes = np.array([self._slope(x, v, s, R) for s in steps])
            clear = np.flatnonzero(np.isfinite(slopes) & (np.abs(slopes) > noise))
            if clear.size == 0:
                shapes.append("flat")
                continue
            last = clear[-1]  # the shortest step that still shows U change: its sign
            shapes.append("rises" if slopes[last] > 0 else "falls")
            if last - 1 in clear and slopes[last - 1] * slopes[last] > 0:
                # dU/ds ~ c s^(p-1): halving s divides it by 2^(p-1)
                p = 1.0 + math.log2(slopes[last - 1] / slopes[last])
                if abs(p - round(p)) < 0.25 and round(p) >= 2:
                    orders.append(round(p))
        order = max(orders) if orders else None
        if all(shape == "flat" for shape in shapes):
            return "flat", None
        if all(shape == "rises" for shape in shapes):
            return "rises", order
        if d == 1 and set(shapes) == {"rises", "falls"}:
            return "odd", order
        if "falls" in shapes:
            return "falls", order
        return "mixed", order

    def _slope(self, x, v, s, R) -> float:
        """dU/ds at ``x + s v`` with the directions ``R`` (columns) relaxed to dU = 0 there
        (Newton); by the envelope theorem the slope of U along the reduced path."""
        y = x + s * v
        for _ in range(30):
            if R.shape[1] == 0:
                break
            g = self.gradient(*y)
            J = R.T @ self.hessian(y) @ R
            try:
                step = R @ np.linalg.solve(J, R.T @ g)
            except np.linalg.LinAlgError:
                return math.nan
            y = y - step
            if not np.all(np.isfinite(y)):
                return math.nan
            if np.linalg.norm(step) <= 1e-15 * (1.0 + np.linalg.norm(y)):
                break
        return float(v @ self.gradient(*y))

    # -- sets of equilibria ---------------------------------------------------------------

    def classify(self, found: list[tuple[np.ndarray, dict[str, str]]]) -> list[Equilibrium]:
        """One ``Equilibrium`` per isolated point and one per set of them (``continuum``)."""
        equilibria: list[Equilibrium] = []
        sets: list[dict] = []
        flat_minima: list[np.ndarray] = []  # traces through flat points that are no sets
        singular: list[tuple[np.ndarray, Equilibrium]] = []  # at chart singularities
        for point, exact in found:
            if any(self.distance(point, trace).min() <= self.trace_step for trace in flat_minima):
                continue  # the same flat point, found again where U is numerically flat
            member = self._member(point, sets)
            if member is not None:
                member["found"] += 1
                member["points"].append(point)
                continue
            if self.chart_singular(self.mass(self.full(point))):
                # one configuration, many points of the chart (theta = 0, every phi)
                if not any(self._one_configuration(point, other) for other, _ in singular):
                    singular.append((point, self.equilibrium(point, exact)[0]))
                continue
            equilibrium, flat = self.equilibrium(point, exact)
            if flat == 1:
                curve, closed = self.trace(point)
                decided = self._not_an_interval(point, curve) if len(curve) >= 3 else None
                if decided is not None:
                    verdict, order = decided
                    equilibrium = replace(
                        equilibrium,
                        stable=verdict.startswith("stable"),
                        verdict=verdict,
                        order=order,
                        frequencies=[],
                        decided_by=_VERDICTS[verdict].format(
                            zeros=_zeros(1), s="", order=f" as the power {order} of the distance"
                        ),
                    )
                    equilibria.append(equilibrium)
                    flat_minima.append(curve)
                    continue
                if len(curve) >= 3:
                    sets.append(
                        {
                            "dimension": 1,
                            "curve": curve,
                            "closed": closed,
                            "found": 1,
                            "points": [point],
                            "level": equilibrium.potential,
                        }
                    )
                    continue
            elif flat >= 2:
                sets.append(
                    {
                        "dimension": flat,
                        "curve": None,
                        "closed": False,
                        "found": 1,
                        "points": [point],
                        "level": equilibrium.potential,
                    }
                )
                continue
            if flat:
                equilibrium = replace(
                    equilibrium,
                    stable=False,
                    verdict="undecided",
                    frequencies=[],
                    decided_by=_VERDICTS["undecided"].format(zeros=_zeros(flat), order=""),
                )
            equilibria.append(equilibrium)
        for point, equilibrium in singular:
            on = next((record for record in sets if self._on_set(point, record)), None)
            if on is None:
                equilibria.append(equilibrium)
            else:  # a point of the set where the chart fails: the set decides
                on["found"] += 1
        return equilibria + [self._set_equilibrium(record) for record in sets]

    def _one_configuration(self, a: np.ndarray, b: np.ndarray) -> bool:
        """True if the chart-singular points ``a`` and ``b`` are one configuration: the
        particles at the same places, or (without particles) U the same at both and the
        chart singular all along the segment between them."""
        position = self.position()
        if position is not None:
            ra, rb = position(self.full(a)), position(self.full(b))
            return bool(np.linalg.norm(ra - rb) <= 1e-7 * max(1.0, float(np.max(np.abs(ra)))))
        level_a, level_b = float(self.U(*a)[0]), float(self.U(*b)[0])
        if abs(level_a - level_b) > 1e-9 * max(1.0, abs(level_a)):
            return False
        step = np.where(self.is_periodic, _wrapped(b - a), b - a)
        return all(
            self.chart_singular(self.mass(self.full(a + s * step)))
            for s in np.linspace(0.0, 1.0, 9)
        )

    def _on_set(self, point: np.ndarray, record: dict) -> bool:
        """True if the chart-singular ``point`` is a point of the set ``record`` (a
        curve): the same configuration as one of its points, or, without particles, a
        point of the curve in the chart."""
        curve = record["curve"]
        if curve is None:
            return False
        position = self.position()
        if position is None:  # the curve meets the singular line ``point`` lies on
            M = self.mass(self.full(point))
            _, values, vectors = np.linalg.svd(M)
            kernel = vectors[values <= 1e-13 * max(float(values[0]), 1e-300)]
            index_r = [self.names.index(name) for name in self.searched]
            if len(kernel) != 1 or not np.any(kernel[0][index_r]):
                return False
            direction = kernel[0][index_r] * self.scales
            line = point[: self.mq] + np.linspace(-math.pi, math.pi, 1441)[:, None] * direction
            # with the point's multipliers, where U is W = U + lambda . c (constraints)
            line = np.hstack(
                [line, np.broadcast_to(point[self.mq :], (len(line), self.m - self.mq))]
            )
            if not all(self._one_configuration(point, p) for p in line[::160]):
                return False  # not a straight line of the chart's singular set
            return bool(min(self.distance(p, curve).min() for p in line) <= 2 * self.trace_step)
        target = position(self.full(point))
        images = np.array([position(self.full(c)) for c in curve])
        gaps = np.linalg.norm(np.diff(images, axis=0), axis=1)
        reach = 2.0 * float(np.max(gaps)) if gaps.size else 0.0
        return bool(np.linalg.norm(images - target, axis=1).min() <= reach)

    def _not_an_interval(self, x: np.ndarray, curve: np.ndarray) -> tuple[str, int] | None:
        """For one searched coordinate: ``(verdict, order)`` when the "curve" traced
        through ``x`` is no interval of equilibria, None when it is (or for more
        coordinates).

        On a line a set of equilibria is an interval where U is constant. A flat minimum
        (``x**8``, ``k*x**10``) has a gradient below the search's noise floor (set by the
        largest gradient in the box) over a whole interval, which the trace follows; but
        U itself is not constant there: it grows as a power of the distance, whose sign
        on each side and exponent decide the verdict.
        """
        if self.mq != 1 or curve.shape[1] != 1:
            return None
        with np.errstate(all="ignore"):
            level = float(self.U(*x)[0])
            values = np.array([float(self.U(*p)[0]) for p in curve])
        change = values - level
        scale = np.maximum(np.abs(values), abs(level))
        if not np.all(np.isfinite(change)) or np.all(np.abs(change) <= 1e-9 * scale):
            return None
        offset = curve[:, 0] - x[0]
        sides = []
        for side in (offset > 0, offset < 0):
            moved = change[side]
            moved = moved[np.abs(moved) > 1e-9 * scale[side]]
            sides.append(0 if not moved.size else int(np.sign(moved[np.argmax(np.abs(moved))])))
        if 0 in sides:
            return None
        if sides[0] == sides[1]:
            verdict = "stable: rises" if sides[0] > 0 else "unstable: falls"
        else:
            verdict = "unstable: odd"
        order = 0
        useful = (np.abs(offset) > 0) & (np.abs(change) > 1e-9 * scale)
        if np.count_nonzero(useful) >= 2:
            slope = np.polyfit(np.log(np.abs(offset[useful])), np.log(np.abs(change[useful])), 1)
            order = int(round(float(slope[0])))
        if order < 3:  # a quadratic term would have shown in K
            return None
        return verdict, order

    def _member(self, x: np.ndarray, sets: list[dict]) -> dict | None:
        for record in sets:
            if record["curve"] is not None:
                if self.distance(x, record["curve"]).min() <= self.trace_step:
                    return record
            elif abs(float(self.U(*x)[0]) - record["level"]) <= 1e-9 * (1 + abs(record["level"])):
                eig = np.linalg.eigvalsh(self.hessian(x))
                tol = 1e-8 * max(self.hessian_scale, float(np.max(np.abs(eig))))
                if np.count_nonzero(np.abs(eig) <= tol) >= record["dimension"]:
                    return record
        return None

    def distance(self, x: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Euclidean distances from ``x`` to each row of ``points`` (angles mod 2 pi)."""
        d = np.abs(np.asarray(points) - x)
        d = np.where(self.is_periodic, np.mod(d, 2 * math.pi), d)
        d = np.where(self.is_periodic, np.minimum(d, 2 * math.pi - d), d)
        return np.linalg.norm(d, axis=-1)

    def trace(self, x0: np.ndarray, limit: int = 2000) -> tuple[np.ndarray, bool]:
        """Follow the curve of equilibria through ``x0`` by pseudo-arclength continuation.

        Returns
        -------
        points : ndarray, shape (k, m)
            Points along the curve, in order, spaced by about ``trace_step``; fewer than 3
            when there is no curve (U is flat only to the order the probe resolved).
        closed : bool
            True when the curve came back to ``x0``.
        """
        h = self.trace_step

        def tangent(x, previous):
            w, V = np.linalg.eigh(self.hessian(x))  # x was accepted: K is finite there
            t = V[:, int(np.argmin(np.abs(w)))]
            return t if previous is None or t @ previous >= 0 else -t

        def correct(y, t):
            x = y.copy()
            for _ in range(25):
                g = self.gradient(*x)
                F = np.append(g, t @ (x - y))
                J = np.vstack([self.hessian(x), t])
                if not (np.all(np.isfinite(F)) and np.all(np.isfinite(J))):
                    return None
                try:
                    dx = np.linalg.lstsq(J, -F, rcond=None)[0]
                except np.linalg.LinAlgError:
                    return None
                x = x + dx
                if np.linalg.norm(dx) <= 1e-14 * (1.0 + np.linalg.norm(x)):
                    break
            return self.accept(x, inside_only=True) if np.linalg.norm(x - y) < h else None

        t0 = tangent(x0, None)
        halves: list[list[np.ndarray]] = []
        for sign in (1.0, -1.0):
            x, t, half = x0, sign * t0, []
            for _ in range(limit):
                nxt = correct(x + h * t, t)
                if nxt is None or self.distance(nxt, np.array([x]))[0] < 0.25 * h:
                    break
                # unfold the angles, so the curve is continuous through +-pi
                nxt = np.where(self.is_periodic, x + _wrapped(nxt - x), nxt)
                half.append(nxt)
                if len(half) >= 3 and self.distance(nxt, x0[None, :])[0] < 0.75 * h:
                    half.pop()
                    return np.array([x0, *half]), True
                x, t = nxt, tangent(nxt, t)
            halves.append(half)
        forward, backward = halves
        points = np.array([*backward[::-1], x0, *forward])
        return points, False

    def _representative(self, curve: np.ndarray) -> np.ndarray:
        """A point of the curve where a coordinate is 0 (the last such coordinate, the
        largest such point), refined onto the set; else the curve's first point."""
        for j in reversed(range(self.mq)):
            column = curve[:, j]
            if self.is_periodic[j]:
                column = _wrapped(column)
            crossings = np.flatnonzero(np.sign(column[:-1]) != np.sign(column[1:]))
            candidates = []
            for i in crossings:
                a, b = column[i], column[i + 1]
                if abs(b - a) > 4 * self.trace_step:  # a jump of an angle through pi
                    continue
                w = a / (a - b) if a != b else 0.0
                start = curve[i] + w * (curve[i + 1] - curve[i])
                start = np.where(self.is_periodic, _wrapped(start), start)
                x = self._on_set_with_zero(start, [j])
                if x is not None and self.conditioning(x) > REGULAR_CHART:
                    candidates.append(x)
            if candidates:
                return max(candidates, key=lambda x: tuple(np.round(x, 9)))
        return self._most_regular(curve)

    def _most_regular(self, points: np.ndarray) -> np.ndarray:
        """The point of ``points`` where M is best conditioned (the first of equals, to
        rounding): the stability of a set is decided at a regular point of the chart."""
        conditions = np.round([self.conditioning(p) for p in points], 6)
        best = points[int(np.argmax(conditions))]
        return np.where(self.is_periodic, fold_angle(best), best)

    def _on_set_with_zero(self, start: np.ndarray, zeros: list[int]) -> np.ndarray | None:
        """The point of the set near ``start`` where the coordinates ``zeros`` are 0, or
        None (least squares on dU/dq = 0 and those coordinates)."""
        scale = self.gradient_scale

        def residual(x):
            return np.append(self.gradient(*x) / scale, x[zeros])

        def jacobian(x):
            return np.vstack([self.hessian(x) / scale, np.eye(self.m)[zeros]])

        import scipy.optimize

        with np.errstate(all="ignore"):
            try:
                solution = scipy.optimize.least_squares(
                    residual, start, jac=jacobian, method="lm", xtol=1e-15, ftol=1e-15
                )
            except (ValueError, np.linalg.LinAlgError):
                return None
        x = solution.x
        x[zeros] = np.where(np.abs(x[zeros]) < 1e-12, 0.0, x[zeros])
        if np.any(x[zeros] != 0.0) or np.linalg.norm(x - start) > 4 * self.trace_step:
            return None
        return self.accept(x, inside_only=False)

    def _surface_point(self, points: np.ndarray, dimension: int) -> np.ndarray:
        """A point of a surface of equilibria with its last ``dimension`` coordinates 0 if
        there is one near the points found, else the first point found."""
        for count in range(min(dimension, self.mq), 0, -1):
            zeros = list(range(self.mq - count, self.mq))
            # nearest to those coordinates' zeros; among equals, the largest first coordinate
            off = np.round(np.linalg.norm(points[:, zeros], axis=1), 6)
            start = points[int(np.lexsort((-points[:, 0], off))[0])]
            x = self._on_set_with_zero(start, zeros) if count else None
            if x is not None and self.conditioning(x) > REGULAR_CHART:
                return x
        return self._most_regular(points)

    def _set_equilibrium(self, record: dict) -> Equilibrium:
        curve = record["curve"]
        dimension = record["dimension"]
        if curve is not None:
            x = self._representative(curve)
            points = np.array([np.where(self.is_periodic, fold_angle(p), p) for p in curve])
        else:
            curve = points = np.array(record["points"])
            x = self._surface_point(points, dimension)
        equilibrium, _ = self.equilibrium(x, {})
        points, curve = points[:, : self.mq], curve[:, : self.mq]
        equation = self.equation(points) if self.equation is not None else ""
        full_points = np.zeros((len(points), len(self.names)))
        index_r = [self.names.index(name) for name in self.searched]
        full_points[:, index_r] = points
        momenta = np.array([self.rest_momenta(p) for p in full_points])
        momenta = momenta.reshape(len(points), len(self.names))
        through = ", ".join(_short(equilibrium.q[name]) for name in self.names)
        description = _describe(
            curve,
            x[: self.mq],
            self.searched,
            self.is_periodic[: self.mq],
            record["closed"],
            dimension,
            equation,
        )
        if not description:
            what = {1: "curve", 2: "surface"}.get(dimension, f"{dimension}-dimensional set")
            closed = "closed " if record["closed"] else ""
            description = f"a {closed}{what} of equilibria through ({through})"
        continuum = EquilibriumSet(
            dimension=dimension,
            description=description,
            equation=equation,
            closed=record["closed"],
            points=np.array([[_clean(v) for v in row] for row in full_points]),
            momenta=momenta,
            found=record["found"],
        )
        if equilibrium.stable:
            how = (
                "transversally a minimum of U"
                if "gyroscopic" not in equilibrium.decided_by
                else ("transversally stabilized by the velocity-linear terms")
            )
            decided = f"U is constant along {description}: neutral along it, {how}"
        else:
            decided = f"U is constant along {description}: neutral along it, unstable across it"
        return replace(equilibrium, kind="continuum", decided_by=decided, continuum=continuum)


REGULAR_CHART = 1e-6
"""A set of equilibria is represented by a point where the smallest singular value of M
is above this fraction of its largest (off the chart's singular lines)."""

TANGENT_SPACE = (
    "K and M on the constraints' tangent space (basis Z): "
    "Z\u1d40(U_qq + \u03a3\u03bb\u1d62\u03a6\u1d62,qq)Z and Z\u1d40MZ"
)
"""How the stability of a constrained equilibrium was decided, after the verdict."""


class _ConstrainedProblem(_Problem):
    """Equilibria under acting constraints ``c(q) = 0`` (the holonomic ones and the
    unilateral ones in contact): the stationary points of ``W = U + lambda . c`` over the
    searched coordinates and the multipliers, ``dU/dq + c_q^T lambda = 0`` and ``c = 0``.

    Stability and small oscillations are those of the tangent space: with Z an
    orthonormal basis of ker c_q, the stiffness ``Z^T W_qq Z`` (U's Hessian plus the
    constraints' curvature weighted by their multipliers), the mass ``Z^T M Z`` and the
    gyroscopic ``Z^T G Z``. Along a degenerate direction U is followed on the constraint
    manifold (``_slope``). A continuum of equilibria is a curve of stationary points of
    W, which the continuation follows as without constraints.
    """

    def __init__(
        self,
        mechanics,
        U,
        constraints,
        labels,
        unknowns,
        searched,
        free,
        periodic,
        region,
        parameters,
    ):
        k, mq = len(constraints), len(unknowns)
        self.labels = tuple(labels)
        multipliers = list(sympy.symbols(f"\u03bb1:{k + 1}"))
        W = U + sum(
            (lam * c for lam, c in zip(multipliers, constraints, strict=True)), sympy.S.Zero
        )
        self._values = vectorize(list(constraints), unknowns)
        jacobian = [sympy.diff(c, u) for c in constraints for u in unknowns]
        self._jacobian = vectorize(jacobian, unknowns)
        self._force = vectorize([sympy.diff(U, u) for u in unknowns], unknowns)
        self.k, self._mq = k, mq
        self._row_scale: float | None = None
        super().__init__(
            mechanics, W, [*unknowns, *multipliers], searched, free, periodic, region, parameters
        )
        # the starts balance dU/dq as well as the constraints can, which is exactly where
        # it is normal to them (a ring in a harmonic well): the scale is dU/dq's own
        grid = _Problem.starts(self)
        with np.errstate(all="ignore"):
            force = np.linalg.norm(self._force(*grid.T).reshape(mq, -1), axis=0)
        self.gradient_scale = _typical(force)

    def starts(self) -> np.ndarray:
        """The grid of ``_Problem.starts`` moved onto ``c = 0`` (least-norm Newton steps),
        each with the multipliers that balance dU/dq best there; shape (s, mq + k)."""
        k, mq = self.k, self._mq
        Q = super().starts()
        with np.errstate(all="ignore"):
            for _ in range(30):
                c = self._values(*Q.T).T.reshape(len(Q), k)
                J = self._jacobian(*Q.T).T.reshape(len(Q), k, mq)
                Q = Q - (_pseudo_inverse(J) @ c[..., None])[..., 0]
            c = self._values(*Q.T).T.reshape(len(Q), k)
            J = self._jacobian(*Q.T).T.reshape(len(Q), k, mq)
            f = self._force(*Q.T).T.reshape(len(Q), mq)
            lam = -(_pseudo_inverse(np.swapaxes(J, 1, 2)) @ f[..., None])[..., 0]
        X = np.concatenate([Q, lam], axis=1)
        on = np.all(np.isfinite(X), axis=1) & (
            np.linalg.norm(c, axis=1) <= 1e-9 * (1.0 + np.linalg.norm(Q, axis=1))
        )
        X = X[on]
        # the grid's points crowd together on a lower-dimensional constraint set: one
        # start per cell of a hundredth of the box is enough there
        cell = 0.01 * np.array([hi - lo for lo, hi in self.region.values()])
        _, first = np.unique(np.round(X[:, :mq] / cell).astype(np.int64), axis=0, return_index=True)
        return X[np.sort(first)]

    def tangent(self, x: np.ndarray) -> np.ndarray:
        J = self.hessian(x)[self.mq :, : self.mq]
        _, singular, Vt = np.linalg.svd(J)
        rank = int(np.count_nonzero(singular > 1e-10 * max(float(singular[0]), 1e-300)))
        return Vt[rank:].T

    def complete(self, q: np.ndarray) -> np.ndarray:
        """``(q, lambda)``: the multipliers that balance dU/dq at ``q`` (least squares)."""
        J = self._jacobian(*q).reshape(self.k, self.mq)
        lam = -np.linalg.lstsq(J.T, self._force(*q), rcond=None)[0]
        return np.concatenate([q, lam])

    def equilibrium(self, x: np.ndarray, exact: dict[str, str]) -> tuple[Equilibrium, int]:
        equilibrium, flat = super().equilibrium(x, exact)
        multipliers = {label: _clean(v) for label, v in zip(self.labels, x[self.mq :], strict=True)}
        if self._singular_constraints(x):  # no multipliers, no tangent space there
            equilibrium = replace(
                equilibrium,
                stable=False,
                kind="degenerate",
                verdict="undecided",
                frequencies=[],
                decided_by=SINGULAR_CONSTRAINTS,
            )
            return equilibrium, 0
        if equilibrium.chart:  # a chart singularity: said as it is
            decided, verdict = equilibrium.decided_by, equilibrium.verdict
        elif equilibrium.hessian.size == 0:  # nothing left to move
            decided, verdict = _VERDICTS["stable: fixed"], "stable: fixed"
        else:
            decided, verdict = f"{equilibrium.decided_by}; {TANGENT_SPACE}", equilibrium.verdict
        equilibrium = replace(
            equilibrium, multipliers=multipliers, decided_by=decided, verdict=verdict
        )
        return equilibrium, flat

    def _singular_constraints(self, x: np.ndarray) -> bool:
        """True where the rows c_q lose rank (a cusp or crossing of the constraint set,
        the origin of ``sqrt(x**2 + y**2) - l``): compared with their size at the starts."""
        if self._row_scale is None:
            grid = _Problem.starts(self)
            with np.errstate(all="ignore"):
                rows = self._jacobian(*grid.T).reshape(self.k, self._mq, -1)
            self._row_scale = _typical(np.linalg.norm(rows, axis=1))
        with np.errstate(all="ignore"):
            J = np.asarray(self._jacobian(*x[: self.mq]), dtype=float).reshape(self.k, self.mq)
        if not np.all(np.isfinite(J)):
            return True
        smallest = np.linalg.svd(J, compute_uv=False)[-1] if self.k <= self.mq else 0.0
        return bool(smallest <= 1e-6 * self._row_scale)

    def _slope(self, x, v, s, R) -> float:
        """dU/ds at ``q0 + s v`` moved back onto ``c = 0`` along the normals Y of the
        constraints at ``q0``, with the tangent directions ``R`` relaxed to stationarity:
        ``c = 0``, ``R^T g = 0`` and ``Y^T g = 0`` for ``g = dU/dq + c_q^T lambda`` in the
        unknowns (r, w, lambda). Then g lies along the degenerate directions, and by the
        envelope theorem dU/ds along the path on the manifold is ``v . g``."""
        mq, k = self.mq, self.k
        q0 = x[:mq]
        J0 = self.hessian(x)[mq:, :mq]
        Y = np.linalg.svd(J0)[2][:k].T
        r, w, lam = np.zeros(R.shape[1]), np.zeros(k), x[mq:].copy()
        g = np.full(mq, np.nan)
        for _ in range(30):
            y = q0 + s * v + R @ r + Y @ w
            z = np.concatenate([y, lam])
            gradient, hessian = self.gradient(*z), self.hessian(z)
            g, c = gradient[:mq], gradient[mq:]
            H, J = hessian[:mq, :mq], hessian[mq:, :mq]
            F = np.concatenate([c, R.T @ g, Y.T @ g])
            D = np.block(
                [
                    [J @ R, J @ Y, np.zeros((k, k))],
                    [R.T @ H @ R, R.T @ H @ Y, R.T @ J.T],
                    [Y.T @ H @ R, Y.T @ H @ Y, Y.T @ J.T],
                ]
            )
            try:
                step = np.linalg.solve(D, F)
            except np.linalg.LinAlgError:
                return math.nan
            if not np.all(np.isfinite(step)):
                return math.nan
            nr = R.shape[1]
            r, w, lam = r - step[:nr], w - step[nr : nr + k], lam - step[nr + k :]
            if np.linalg.norm(step) <= 1e-15 * (1.0 + np.linalg.norm(z)):
                break
        y = q0 + s * v + R @ r + Y @ w
        return float(v @ self.gradient(*np.concatenate([y, lam]))[:mq])


SINGULAR_CONSTRAINTS = (
    "the constraints' gradients vanish or are dependent there (a singular point of the "
    "constraint set, such as a cusp or a crossing): no multipliers \u03bb hold it and there is "
    "no tangent space, so the linearisation does not decide"
)

_VERDICTS = {
    "stable: minimum": "U has a strict minimum (K positive definite)",
    "stable: gyroscopic": (
        "gyroscopic stabilization: U has a {kind}, but the gyroscopic terms (of L linear "
        "in the velocities, or effects that do no work) put every eigenvalue of the "
        "linearisation on the imaginary axis"
    ),
    "unstable: linear": "the linearisation has a growing mode (an eigenvalue with positive "
    "real part)",
    "stable: rises": (
        "the linearisation is degenerate ({zeros} of K); U rises along the degenerate "
        "direction{s}{order}: a degenerate minimum, stable (the energy bounds the motion)"
    ),
    "unstable: falls": (
        "the linearisation is degenerate ({zeros} of K); U falls along the degenerate "
        "direction{s}{order}: unstable"
    ),
    "unstable: odd": (
        "the linearisation is degenerate ({zeros} of K); U rises on one side and falls on "
        "the other along the degenerate direction{order}, an inflection: unstable"
    ),
    "stable: flat": "the linearisation is degenerate ({zeros} of K); U is constant along "
    "the degenerate direction{s} (neutral) and has a minimum across",
    "stable: flat gyroscopic": "the linearisation is degenerate ({zeros} of K); U is "
    "constant along the degenerate direction{s} (neutral), stabilized across by the "
    "gyroscopic terms",
    "unstable: flat": "the linearisation is degenerate ({zeros} of K); U is constant along "
    "the degenerate direction{s} and falls across: unstable",
    "stable: fixed": "the constraints fix every coordinate that U depends on",
    "undecided": "the linearisation is degenerate ({zeros} of K) and the terms of U beyond "
    "the quadratic ones do not decide{order}: not known to be stable",
}


def _zeros(count: int) -> str:
    return "a zero eigenvalue" if count == 1 else f"{count} zero eigenvalues"


def _decided_text(verdict, kind, eig_K, null, order, regular, gyroscopic) -> str:
    zeros = int(np.count_nonzero(null))
    text = _VERDICTS[verdict].format(
        kind=kind,
        zeros=_zeros(zeros),
        s="s" if zeros > 1 else "",
        order=f" as the power {order} of the distance" if order else "",
    )
    if verdict == "unstable: linear" and not gyroscopic:
        if zeros:
            text = f"K has a negative eigenvalue besides {_zeros(zeros)}: U falls that way"
        else:
            text = f"U has a {kind} (K has a negative eigenvalue)"
    if verdict.startswith("stable") and not regular:
        text += "; the inertia there is zero or infinite, so there are no small oscillations"
    elif verdict == "stable: minimum" and gyroscopic:
        text += (
            "; the gyroscopic terms (of L linear in the velocities, or effects that do no "
            "work) shift the frequencies"
        )
    return text


def _spectrum(K, M, G, hamiltonian: bool) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (2m,) sorted by imaginary part, and the coordinate parts (m, 2m) of the
    eigenvectors, of ``M qdd + G qdot + K q = 0`` (state (q, qdot)); or, for a
    Hamiltonian-only scene (``M`` is then ``d2H/dp2``, ``G`` is ``d2H/dq dp``), of
    Hamilton's linearised equations ``z' = J Hess(H) z`` (state (q, p))."""
    m = len(K)
    if hamiltonian:
        S = np.block([[K, G], [G.T, M]])
        A = np.block([[S[m:]], [-S[:m]]])  # J S with J = [[0, I], [-I, 0]]
    else:
        A = np.block(
            [[np.zeros((m, m)), np.eye(m)], [-np.linalg.solve(M, K), -np.linalg.solve(M, G)]]
        )
    values, vectors = np.linalg.eig(A)
    order = np.lexsort((values.real, values.imag))
    shapes = vectors[:m, order]
    big = np.argmax(np.abs(shapes), axis=0)
    pivot = shapes[big, np.arange(shapes.shape[1])]
    shapes = shapes / np.where(np.abs(pivot) > 0, pivot, 1.0)
    return values[order], shapes


def _wrapped(angle):
    """An angle (or array of them) moved into [-pi, pi)."""
    return np.mod(np.asarray(angle) + math.pi, 2 * math.pi) - math.pi


def _short(value: float) -> str:
    text = f"{_clean(value):.6g}"
    return "0" if text == "-0" else text


def _describe(points, through, names, periodic, closed: bool, dimension: int, equation: str) -> str:
    """A set of equilibria for a person, from points on it (shape (k, m), angles unfolded
    along a curve) and one point ``through`` (m,) of it: ``"the circle x² + y² = 1"`` when
    the points lie on a circle in the plane of two (non-angle) coordinates, the others
    fixed; ``"the straight line through (0, 0) along (1, 0.5)"``; ``"the curve
    <equation>"`` when sympy gave one; or "" (the caller says "a curve through ...")."""
    spread = np.ptp(points, axis=0)
    moving = np.flatnonzero(spread > 1e-9 * (1.0 + np.max(np.abs(points), axis=0)))
    fixed = [f"{names[i]} = {_short(points[0, i])}" for i in range(len(names)) if i not in moving]
    at = f" at {', '.join(fixed)}" if fixed and dimension == 1 else ""
    if dimension == 1 and closed and len(moving) == 2 and not np.any(periodic[moving]):
        xy = points[:, moving]
        A = np.column_stack([2 * xy, np.ones(len(xy))])
        b = np.sum(xy**2, axis=1)
        (a, c, k), *_ = np.linalg.lstsq(A, b, rcond=None)
        r2 = k + a * a + c * c
        if r2 > 0:
            r = math.sqrt(r2)
            off = np.abs(np.hypot(xy[:, 0] - a, xy[:, 1] - c) - r)
            if np.max(off) <= 1e-7 * r:
                u, v = (names[i] for i in moving)
                return f"the circle {_square(u, a)} + {_square(v, c)} = {_short(r2)}{at}"
    if dimension == 1 and len(points) >= 3 and moving.size and points.shape[1] >= 2:
        centred = points - points.mean(axis=0)
        singular = np.linalg.svd(centred, compute_uv=False)
        if singular[1] <= 1e-9 * singular[0]:
            direction = np.linalg.svd(centred)[2][0]
            direction = direction / direction[np.argmax(np.abs(direction))]
            through = ", ".join(_short(v) for v in through)
            along = ", ".join(_short(v) for v in direction)
            return f"the straight line through ({through}) along ({along})"
    if equation:
        what = {1: "curve", 2: "surface"}.get(dimension, "set")
        return f"the {what} {equation}"
    return ""


def _square(name: str, centre: float) -> str:
    if abs(centre) < 1e-9:
        return f"{name}²"
    sign = "-" if centre > 0 else "+"
    return f"({name} {sign} {_short(abs(centre))})²"


class _Cross:
    """The terms of the quadratic Lagrangian that couple velocities and coordinates.

    ``gyroscopic(q, index_r, index_f, back)`` gives ``(G, hamiltonian)``: G (m, m) or None
    when there are no such terms. For a Lagrangian, ``G = C - C^T`` with
    ``C = d a / d q`` (a = p at rest), reduced onto the searched coordinates with the free
    coordinates' momenta held at zero (``C_rr + back^T C_fr``). For a Hamiltonian-only
    scene, ``H_qp`` (``G[i, j] = d2H/dq_i dp_j``) over the searched coordinates (then
    ``hamiltonian`` is True and the spectrum comes from Hamilton's linearised equations;
    the search itself still uses U = H(q, p = 0)).
    """

    def __init__(self, function, hamiltonian: bool, n: int, effects=None):
        self.function, self.hamiltonian, self.n = function, hamiltonian, n
        self.effects = effects
        """None, or ``B(q)`` with ``B[i, j] = dQ_i/dqdot_j`` at rest of effects that do
        no work: ``M qdd + (C - C^T - B) qdot + K q = 0``."""

    def gyroscopic(self, q, index_r, index_f, back):
        if self.function is None and self.effects is None:
            return None, self.hamiltonian
        if self.function is None:
            C = np.zeros((self.n, self.n))
        else:
            C = np.asarray(self.function(*q), dtype=float).reshape(self.n, self.n)
        if self.hamiltonian:  # C[i, j] = d2H/dp_i dq_j: G = H_qp is its transpose
            block = C[np.ix_(index_r, index_r)].T
            big = float(np.max(np.abs(block), initial=0.0))
            return (block if big > 0 else None), True
        reduced = C[np.ix_(index_r, index_r)]
        if index_f:
            reduced = reduced + back.T @ C[np.ix_(index_f, index_r)]
        G = reduced - reduced.T
        big = float(np.max(np.abs(G), initial=0.0))
        # a symmetric C (a total time derivative in L) leaves only rounding errors
        if not big > 1e-10 * float(np.max(np.abs(reduced), initial=0.0)):
            G = np.zeros_like(G)
        if self.effects is not None:
            B = np.asarray(self.effects(*q), dtype=float).reshape(self.n, self.n)
            # a free coordinate's momentum is held at zero as above; the effects' part
            # along it is left out (it is not conserved under them)
            G = G - B[np.ix_(index_r, index_r)]
        if not float(np.max(np.abs(G), initial=0.0)) > 0:
            return None, False
        return G, False


def _cross_function(mechanics: Mechanics, momenta, parameters) -> _Cross:
    """``_Cross`` for the scene: da/dq from the momenta at rest, or d2H/dq dp at p = 0."""
    n = mechanics.n
    if mechanics.lagrangian is None:
        zero = {**dict.fromkeys(mechanics.p, 0), mechanics.t: 0}
        H = with_parameters(mechanics.hamiltonian, mechanics, parameters)
        engine = Calculus(mechanics.scene.symbols.values())
        rows = [engine.gradient(d, mechanics.q) for d in engine.gradient(H, mechanics.p)]
        entries = [e.xreplace(zero) for row in rows for e in row]
        if all(e == 0 for e in entries):
            return _Cross(None, True, n)
        return _Cross(vectorize(entries, mechanics.q), True, n)
    effects = None
    if _gyroscopic_effects(mechanics):
        zero = dict.fromkeys(mechanics.qdot, sympy.S.Zero)
        entries = [
            with_parameters(sympy.diff(f, v), mechanics, parameters).xreplace(zero)
            for f in mechanics.generalized_forces
            for v in mechanics.qdot
        ]
        effects = vectorize(entries, mechanics.q)
    if all(sympy.S(a) == 0 for a in momenta):
        return _Cross(None, False, n, effects)
    engine = Calculus(mechanics.scene.symbols.values())
    rows = [engine.gradient(a, mechanics.q) for a in momenta]
    return _Cross(vectorize([e for row in rows for e in row], mechanics.q), False, n, effects)


def _set_equation_finder(mechanics, U, unknowns, timeout: float, parameters, region):
    """A function ``points (k, m) -> str``: the factor ``f`` common to every component of
    dU/dq (sympy, in a child process stopped after ``timeout`` seconds, parameters
    symbolic) that vanishes at all the points, written ``"lhs = rhs"``; "" if none. None
    when ``timeout`` is 0 (no symbolic work wanted)."""
    if timeout <= 0:
        return None

    def find(points: np.ndarray) -> str:
        cache = cache_for(mechanics)
        key = ("equilibria.common_factors", tuple(unknowns))
        if key not in cache:
            gradient = [sympy.diff(U, u) for u in unknowns]
            too_big = sum(g.count_ops() for g in gradient) > SYMBOLIC_MAX_OPS
            cache[key] = (
                None if too_big else run_bounded(_common_factors, (gradient, unknowns), timeout)
            )
        lows = np.array([lo for lo, _ in region.values()])
        highs = np.array([hi for _, hi in region.values()])
        away = np.random.default_rng(11).uniform(lows, highs, size=(64, len(unknowns)))
        for factor in cache[key] or []:
            f = vectorize([with_parameters(factor, mechanics, parameters)], unknowns)
            on, off = np.abs(f(*points.T)[0]), np.abs(f(*away.T)[0])
            typical = _typical(off)
            if np.all(np.isfinite(on)) and float(np.max(on)) <= 1e-8 * typical:
                constant, rest = factor.as_coeff_Add()
                if constant != 0 and rest != 0:
                    return f"{sympy.sstr(rest)} = {sympy.sstr(-constant)}"
                return f"{sympy.sstr(factor)} = 0"
        return ""

    return find


def _common_factors(gradient, unknowns):
    """Runs in the child process: the irreducible factors of the greatest common divisor
    of the numerators of ``gradient`` that contain an unknown."""
    numerators = [sympy.fraction(sympy.together(g))[0] for g in gradient]
    common = numerators[0]
    for g in numerators[1:]:
        common = sympy.gcd(common, g)
    if not common.has(*unknowns):
        return []
    return [f for f, _ in sympy.factor_list(common)[1] if f.has(*unknowns)]


def _derivatives(mechanics: Mechanics, U: sympy.Expr, unknowns) -> tuple[list, list]:
    """dU/dq and d2U/dq2 (row major) over ``unknowns``, by symengine where it can (sympy's
    diff took half a second for a five-link chain's 25 second derivatives)."""
    engine = Calculus(mechanics.scene.symbols.values())
    try:
        e = engine.to_engine(U)
        xs = [engine.variable(u) for u in unknowns]
        first = [e.diff(x) for x in xs]
        second = [g.diff(x) for g in first for x in xs]
        return [engine.to_sympy(g) for g in first], [engine.to_sympy(h) for h in second]
    except (Unsupported, KeyError):  # KeyError: a multiplier, not a scene symbol
        gradient = [sympy.diff(U, u) for u in unknowns]
        return gradient, [sympy.diff(g, u) for g in gradient for u in unknowns]


def _unique(found, problem: _Problem):
    unique = []
    points = []
    for point, exact in found:
        i = problem.index(point, points)
        if i >= 0:
            if exact and not unique[i][1]:
                unique[i] = (point, exact)
                points[i] = point
        else:
            unique.append((point, exact))
            points.append(point)
    return unique


NEWTON_ITERATIONS = 200
"""Most Newton steps from the starts (all at once; a regular root takes a handful, a
degenerate one such as x**6's about 150, converging linearly); a start not at a root by
then is handed to scipy's hybrid method, which is allowed as many evaluations."""
MAX_COMBINED_ROOTS = 4096
"""At most this many combinations of independent blocks' roots are formed (a twelve-link
chain has 4096 equilibria); beyond, the whole space is scanned from ``_unit_starts``."""


def _blocks(pattern: list[bool], m: int) -> list[list[int]]:
    """The connected components of the coordinates coupled by the Hessian's structural
    nonzeros (``pattern``, row major, m x m): blocks of dU/dq that can be solved alone."""
    parent = list(range(m))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(m):
        for j in range(i + 1, m):
            if pattern[i * m + j] or pattern[j * m + i]:
                parent[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(m):
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


HALTON_STARTS = 400
"""Starting points in four or more dimensions (a shifted Halton set)."""


def _generalized_eigh(K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``K v = w2 M v`` for symmetric K and positive definite M, as
    ``scipy.linalg.eigh(K, M)``: ascending w2, vectors with ``v^T M v = 1``. Through
    M's Cholesky factor with numpy (scipy.linalg costs a quarter of a second to import).

    Raises
    ------
    numpy.linalg.LinAlgError
        If M is not positive definite.
    """
    factor = np.linalg.cholesky(M)
    inverse = np.linalg.inv(factor)
    A = inverse @ K @ inverse.T
    w2, y = np.linalg.eigh((A + A.T) / 2)
    return w2, inverse.T @ y


def _unit_starts(m: int) -> np.ndarray:
    """Starting points in the unit cube, shape (s, m), kept off its faces (and off 0
    exactly, often singular): a grid for m <= 3, a Halton set beyond (the radical
    inverses in the first m primes, shifted by a fixed random vector modulo 1; written
    here because ``scipy.stats.qmc`` costs half a second to import)."""
    if m <= 3:
        count = {1: 41, 2: 15, 3: 8}[m]
        axes = [np.linspace(0.0, 1.0, count) for _ in range(m)]
        unit = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, m)
    else:
        primes: list[int] = []
        candidate = 2
        while len(primes) < m:
            if all(candidate % p for p in primes):
                primes.append(candidate)
            candidate += 1
        index = np.arange(1, HALTON_STARTS + 1)
        unit = np.empty((HALTON_STARTS, m))
        for j, base in enumerate(primes):
            value, scale, rest = np.zeros(HALTON_STARTS), 1.0 / base, index.copy()
            while np.any(rest):
                value += scale * (rest % base)
                rest //= base
                scale /= base
            unit[:, j] = value
        unit = np.mod(unit + np.random.default_rng(3).random(m), 1.0)
    return 0.01 + 0.98 * unit


def _mass_function(mechanics: Mechanics, parameters):
    """M(q) at zero velocities and t = 0, as ``f(q (n,)) -> ndarray (n, n)``."""
    key = ("equilibria.mass", tuple(sorted((parameters or {}).items())))
    cache = cache_for(mechanics)
    if key in cache:
        return cache[key]
    n = mechanics.n
    zero = {**dict.fromkeys(mechanics.qdot, 0), **dict.fromkeys(mechanics.p, 0), mechanics.t: 0}
    if mechanics.mass_matrix is not None:
        entries = [e.xreplace(zero) for e in mechanics.mass_matrix]
        # symengine's Lambdify, made in milliseconds (lambdify printed a six-link chain's
        # M for a third of its equilibrium search), the parameters its arguments (putting
        # sympy Floats into 36 entries cost as much); M is only wanted at one point at a time
        values = parameter_values(mechanics, parameters)
        f = fast_function([*mechanics.q, *values], entries)
        numbers = np.array(list(values.values()), dtype=float)

        def mass(q):
            try:
                return f(np.concatenate([np.asarray(q, dtype=float), numbers])).reshape(n, n)
            except (ValueError, ZeroDivisionError, OverflowError):  # sympy's math fallback
                return np.full((n, n), np.nan)

    else:  # M = (d2H/dp2)^-1 at p = 0
        H = with_parameters(mechanics.hamiltonian, mechanics, parameters)
        W = [sympy.diff(H, a, b).xreplace(zero) for a in mechanics.p for b in mechanics.p]
        f = vectorize(W, mechanics.q)

        def mass(q):
            try:
                return np.linalg.inv(f(*q).reshape(n, n))
            except np.linalg.LinAlgError:
                return np.full((n, n), np.nan)

    cache[key] = mass
    return mass


def _regular(M: np.ndarray) -> bool:
    """True if the mass matrix ``M`` is finite and invertible (not merely numerically)."""
    if M.size == 0 or not np.all(np.isfinite(M)):
        return False
    singular = np.linalg.svd(M, compute_uv=False)
    return bool(singular[-1] > 1e-13 * singular[0])


def _typical(values: np.ndarray) -> float:
    values = np.asarray(values, dtype=float).ravel()
    values = values[np.isfinite(values) & (values > 0)]
    return float(np.median(values)) if values.size else 1.0


def _clean(value: float) -> float:
    value = float(value)
    return 0.0 if abs(value) < 1e-12 else value


def _pseudo_inverse(J: np.ndarray) -> np.ndarray:
    """``np.linalg.pinv`` of a stack of matrices, shape (s, a, b) -> (s, b, a), NaN for
    a matrix with a non-finite entry (a start where a constraint's gradient is 0/0, as
    sqrt(x**2 + z**2) has at the origin): such a start is dropped, not the search."""
    result = np.full((J.shape[0], J.shape[2], J.shape[1]), np.nan)
    finite = np.all(np.isfinite(J), axis=(1, 2))
    if finite.any():
        result[finite] = np.linalg.pinv(J[finite])
    return result
