"""The integration methods by name, grouped in families: the one place that says what a
method is, what it needs and what it takes.

Like scipy's ``METHODS``. A ``Family`` declares its runner, its compiled kernel (the
``X_step`` of ``systems.integrators.kernels``, driven by ``X_run`` and, for ensembles,
``X_ensemble_parallel``), its coefficients, the setting it takes (``dt``, ``ds`` or
``tol``) and the rule for its default, what it needs compiled, and ``applies_to``: None or
the reason it cannot integrate a given system without dropping part of it. A ``Stepper``
is one method of a family (order, weights or stages). The automatic choice, the command
line, the window's method list, ensembles and work-precision sweeps ask this module and
nothing else.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from systems.constraints import PRIMITIVES
from systems.integrators import runners, stepsize
from systems.integrators.tableaux import (
    EXPLICIT_TABLEAUX,
    LEAPFROG,
    TRIPLE_JUMP,
    YOSHIDA6,
    YOSHIDA8,
    dop853_coefficients,
    gauss_tableau,
    kick_drift,
    symplectic_weights,
)

SETTINGS = {"dt": "a time step", "ds": "a fictitious-time step", "tol": "a tolerance"}
GAUSS_MAXIT = 50


@dataclass(frozen=True)
class Family:
    """A kind of method: everything that is the same for all its members.

    Attributes
    ----------
    kernel : str or None
        Prefix of the compiled step and drivers (``{kernel}_run``); None for scipy's.
    setting : {"dt", "ds", "tol"}
        What the user sets: a fixed step, a fictitious-time step, or a tolerance.
    runner : type
        A runner class of ``systems.integrators.runners``.
    coefficients : callable(stepper, compiled, t0, y0, compensated) -> tuple
        The kernel's ``coef`` tuple.
    default_setting : callable(compiled, stepper, t0, y0, t_end, *, probe_start) -> float
    applies : callable(mechanics, stepper) -> str or None
    wants : frozenset of str
        What ``compile_system`` must provide besides ``rhs``.
    functions : tuple of str
        The system functions its step calls, in the order of the kernels' ``fns`` tuple
        (names of ``systems.codegen.SIGNATURES``).
    """

    name: str
    description: str
    kernel: str | None
    setting: str
    runner: type
    coefficients: Callable | None
    default_setting: Callable
    applies: Callable
    wants: frozenset[str] = frozenset()
    functions: tuple[str, ...] = ("rhs",)
    fused: tuple[str, tuple[str, ...]] | None = None
    """(kernel, functions): a second instantiation of the family's loops whose step calls
    these system functions instead (the composition's ``composef``: its stages in one
    call of the scene's ``compose_stages``), taken by a single trajectory's runner
    wherever the compiled system offers them all (the LLVM backend), bitwise the same
    results; ensembles and the chaos maps keep ``kernel``."""
    symplectic: bool = False
    needs_separable: bool = False
    time_transformed: bool = False
    adaptive: bool = False
    ensemble: bool = False
    adaptive_ensemble: bool = False
    """Ensembles of adaptive steps (``X_ensemble_adaptive_parallel``): each row its own
    steps, its states at common times from the family's dense output."""
    batch: tuple[str, str] | None = None
    """An ensemble loop over batches of rows (its kernel, and the batch function of
    ``systems.codegen.SIGNATURES`` it takes), used for adaptive ensembles instead of
    ``X_ensemble_adaptive_parallel``."""
    teaching: bool = False
    constrained: bool = False
    """Projects onto the constraints after every step: only these families integrate a
    scene with ``[constraints]``, and only scenes with constraints."""

    @property
    def run_kernel(self) -> str | None:
        return None if self.kernel is None else f"{self.kernel}_run"

    def loops_for(self, compiled) -> tuple[str, tuple[str, ...]]:
        """(kernel, system functions) a single trajectory of ``compiled`` runs with: the
        ``fused`` ones where ``compiled`` offers their functions, else ``kernel`` and
        ``functions`` (also for a system that does not say, a chaos map's tangent
        system)."""
        offers = getattr(compiled, "offers", None)
        if self.fused is not None and offers and all(offers(name) for name in self.fused[1]):
            return self.fused
        return self.kernel, self.functions

    @property
    def ensemble_kernel(self) -> str | None:
        if self.ensemble:
            return f"{self.kernel}_ensemble_parallel"
        return f"{self.kernel}_ensemble_adaptive_parallel" if self.adaptive_ensemble else None


@dataclass(frozen=True)
class Stepper:
    """One method of a family.

    Attributes
    ----------
    order : int
        Global order of accuracy (error ~ step**order).
    weights : tuple of float
        Composition weights of the leapfrog (composition and log-H families).
    stages : int
        Stages of a Gauss-Legendre method.
    finisher : str
        Time-transformed methods: the fixed-step method that lands on the end time.
    """

    name: str
    order: int
    family: Family
    description: str
    weights: tuple[float, ...] = (1.0,)
    stages: int = 0
    stiff: bool = False
    finisher: str = ""

    symplectic = property(lambda self: self.family.symplectic)
    needs_separable = property(lambda self: self.family.needs_separable)
    adaptive = property(lambda self: self.family.adaptive)
    time_transformed = property(lambda self: self.family.time_transformed)
    setting = property(lambda self: self.family.setting)
    teaching = property(lambda self: self.family.teaching)

    @property
    def wants(self) -> frozenset[str]:
        return self.family.wants | {"rhs"}

    def kick_drift(self) -> tuple[np.ndarray, np.ndarray]:
        """Merged kick and drift coefficients of the composition (see ``tableaux``)."""
        return kick_drift(self.weights)

    def applies_to(self, mechanics) -> str | None:
        """None if this method integrates ``mechanics`` as derived, else why it cannot."""
        reason = _constraints_fit(mechanics, self)
        if reason:
            return reason
        return self.family.applies(mechanics, self)

    def default_setting(
        self,
        compiled,
        t0: float,
        y0: np.ndarray,
        t_end: float,
        probe_start: tuple[float, np.ndarray] | None = None,
    ) -> float:
        """The step or tolerance used when none is given, for a run from ``(t0, y0)``
        (``probe_start``: see ``stepsize.default_step``)."""
        return self.family.default_setting(compiled, self, t0, y0, t_end, probe_start=probe_start)

    def setting_error(
        self,
        dt: float | None = None,
        tol: float | None = None,
        span: tuple[float, float] | None = None,
    ) -> str | None:
        """None if the given settings suit this method (and the run from ``span[0]`` to
        ``span[1]``, when given), else what is wrong and what the method takes."""
        takes = SETTINGS[self.setting]
        if dt is not None and self.setting == "tol":
            return f"{self.name} is adaptive: it takes {takes} (--tol), not a step (--dt)"
        if tol is not None and self.setting != "tol":
            return f"{self.name} takes {takes} (--dt), not a tolerance (--tol)"
        for name, value in (("dt", dt), ("tol", tol)):
            if value is not None and not (math.isfinite(value) and value > 0):
                return f"--{name} must be a positive finite number, not {value!r}"
        if tol is not None and not MIN_TOL <= tol <= 1.0:
            reason = (
                f"--tol {tol:g} is outside what an adaptive method can honour in double "
                f"precision: give a tolerance between {MIN_TOL:g} and 1"
            )
            if self.family.runner is runners.TaylorRunner:  # its tightest setting
                eps = runners.DOUBLE_DOUBLE_BELOW
                reason += (
                    f"; with {self.name} one below machine epsilon ({eps:.2g}), such as "
                    f"{MIN_TOL:g}, carries the state and the series' first two orders in "
                    "double-double"
                )
            return reason
        if dt is not None and self.setting == "dt" and span is not None:
            t0, t_end = span
            length, scale = t_end - t0, max(abs(t0), abs(t_end))
            if math.isfinite(length) and dt > length:
                return f"--dt {dt:g} is longer than the whole run ({length:g}); give a smaller step"
            if math.isfinite(scale) and dt < TIME_RESOLUTION * scale:
                return (
                    f"--dt {dt:g} is below the resolution of the clock near t = {scale:g} "
                    f"(about {TIME_RESOLUTION * scale:.2g}): time would not advance"
                )
        return None


MIN_TOL = 1e-16
"""Smallest tolerance accepted: below it the error estimate is round-off."""

TIME_RESOLUTION = 1e-13
"""Smallest fixed step, relative to the largest |t| of the run: about 500 units of
round-off, so that t + dt moves and the compensated clock stays meaningful."""


# -- applicability ---------------------------------------------------------------------------


def enabled_effects(mechanics) -> list[str]:
    """The scene's effects that are on and not identically zero, in words."""
    forces = getattr(mechanics, "generalized_forces", ())
    if all(_vanishes(f) for f in forces):
        return []
    words = []
    for key in mechanics.scene.enabled_effects():
        if key == "dissipation":
            words.append("dissipation (the Rayleigh function)")
        else:
            words.append(f"driving force on {key.split('.', 1)[1]}")
    return words


def _vanishes(expr) -> bool:
    from systems.expressions import as_expr

    return as_expr(expr) == 0


def _applies_always(mechanics, stepper: Stepper) -> str | None:
    return None


CONSTRAINED_METHODS = "constrained_dop853 or constrained_rk4"
CONSTRAINED_FUNCTIONS = PRIMITIVES
"""The constrained families' steps take these and ``constraints.sizes`` as ``cs``
(``CompiledSystem.constraint_functions``)."""


def _constraints_fit(mechanics, stepper: Stepper) -> str | None:
    """Why ``stepper`` cannot integrate a scene with (or without) constraints."""
    from systems.constraints import constrained as has_constraints

    constrained = has_constraints(mechanics.scene)
    if constrained == stepper.family.constrained:
        return None
    if not constrained:
        return (
            f"{stepper.name} is for scenes with [constraints] (it projects onto them after "
            "every step); this scene has none: use dop853 or rk4"
        )
    if stepper.family.symplectic:
        return (
            f"{stepper.name} would ignore the scene's [constraints]: it steps the free "
            "Hamiltonian, and a symplectic method with constraints needs projections of "
            f"its own (RATTLE), which are not implemented; use {CONSTRAINED_METHODS}"
        )
    return (
        f"{stepper.name} would let the scene's [constraints] drift: it does not project "
        f"onto them after each step; use {CONSTRAINED_METHODS}"
    )


def _splitting_applies(mechanics, stepper: Stepper) -> str | None:
    c = mechanics.classification
    if not c.separable:
        return (
            f"{stepper.name} needs a separable Hamiltonian H = T(p) + V(q, t), and this "
            "system's is not; use gauss_legendre6 or dop853"
        )
    effects = enabled_effects(mechanics)
    if effects:
        return (
            f"{stepper.name} would drop the {' and the '.join(effects)}: its splitting "
            "steps only T(p) and V(q, t); use dop853 or gauss_legendre6, which include it, "
            "or switch the effect off"
        )
    return None


def _logh_applies(mechanics, stepper: Stepper) -> str | None:
    reason = _splitting_applies(mechanics, stepper)
    if reason:
        return reason
    c = mechanics.classification
    if c.time_dependent or not c.hamiltonian_conserved:
        return f"{stepper.name} needs an autonomous system with H conserved; use dop853"
    from systems.integrators.choice import potential_at_start

    value = potential_at_start(mechanics)
    if value is None or not value < 0.0:
        shown = "undefined" if value is None else f"{value:.4g}"
        return (
            f"{stepper.name} steps in a time scaled by 1/(-V), so it needs V < 0 along the "
            f"orbit (an attractive singular potential such as -k/r); V = {shown} at the "
            "initial state. Use yoshida6 or dop853"
        )
    return None


# -- coefficients ----------------------------------------------------------------------------


def _composition_coef(stepper, compiled, t0, y0, compensated):
    kick, drift = stepper.kick_drift()
    return (kick, drift, bool(compensated))


def _logh_coef(stepper, compiled, t0, y0, compensated):
    kick, drift = stepper.kick_drift()
    energy = float(
        compiled.kernels.hamiltonian(float(t0), np.asarray(y0, float), compiled.parameters)
    )
    return (kick, drift, energy, bool(compensated))


def _gauss_coef(stepper, compiled, t0, y0, compensated):
    _, b, c, E = gauss_tableau(stepper.stages)
    return (symplectic_weights(stepper.stages), b, c, E, GAUSS_MAXIT, bool(compensated))


def _gauss_tt_coef(stepper, compiled, t0, y0, compensated):
    _, b, c, E = gauss_tableau(stepper.stages)
    f0 = float(np.linalg.norm(compiled.rhs(t0, y0)))
    power = runners.SUNDMAN_POWER
    return (symplectic_weights(stepper.stages), b, c, E, GAUSS_MAXIT, f0 if f0 > 0 else 1.0, power)


def _explicit_coef(stepper, compiled, t0, y0, compensated):
    A, b, c = EXPLICIT_TABLEAUX[stepper.name]
    return (A, b, c, bool(compensated))


def _fixed_step_constraints_apply(mechanics, stepper: Stepper) -> str | None:
    """A fixed step cannot stop at an impact: unilateral constraints need the adaptive
    family, whose step ends at each located contact."""
    if getattr(mechanics.scene, "unilateral_constraints", ()):
        return (
            f"{stepper.name} takes fixed steps and cannot stop at the impacts of the "
            "scene's unilateral constraints; use constrained_dop853, which locates each "
            "contact and release"
        )
    return None


def _constrained_rk4_coef(stepper, compiled, t0, y0, compensated):
    from systems.constraints import sizes

    A, b, c = EXPLICIT_TABLEAUX["rk4"]
    # each step's projection resets the Kahan terms
    return (A, b, c, False, sizes(compiled.mechanics))


def _dop853_tableau() -> tuple:
    dc = dop853_coefficients()
    return (
        np.ascontiguousarray(dc.A[:12, :12]),
        dc.B.copy(),
        np.ascontiguousarray(dc.C[:12]),
        dc.E3.copy(),
        dc.E5.copy(),
    )


def _dop853_coef(stepper, compiled, t0, y0, compensated):
    """The tableau, then the dense output's three extra stages (A_EXTRA (3, 16),
    C_EXTRA (3,)) and its matrix D (4, 16)."""
    dc = dop853_coefficients()
    n = dc.N_STAGES + 1
    return (
        *_dop853_tableau(),
        np.ascontiguousarray(dc.A[n:]),
        np.ascontiguousarray(dc.C[n:]),
        np.ascontiguousarray(dc.D),
    )


def _constrained_dop853_coef(stepper, compiled, t0, y0, compensated):
    """DOP853's tableau, and ``constraints.sizes``."""
    from systems.constraints import sizes

    return (*_dop853_tableau(), sizes(compiled.mechanics))


def _taylor_applies(mechanics, stepper: Stepper) -> str | None:
    """None when Hamilton's equations decompose into the operations with recurrences
    (``systems.taylor.decompose``) and take no ``abs`` or ``sign`` of the state (their
    series are one side's), else why not (remembered with the derivation)."""
    cache = getattr(mechanics, "_cache", {})
    if "taylor refusal" not in cache:
        from systems.taylor.decompose import NotDecomposable, decompose_mechanics, refusal

        reason = refusal(mechanics)
        if reason is None:
            try:
                kinks = set(decompose_mechanics(mechanics).counts()) & {"abs", "sign"}
            except NotDecomposable as exc:
                reason = str(exc)
            else:
                if kinks:
                    cache["taylor refusal"] = (
                        f"cannot follow a kink: Hamilton's equations take "
                        f"{' and '.join(sorted(kinks))} of the state, whose series follows "
                        "the side it starts on, and a step's length does not see where the "
                        "argument changes sign (in V = |x| one step would cross x = 0 to the "
                        "end of the run); use dop853"
                    )
                    return f"{stepper.name} {cache['taylor refusal']}"
        cache["taylor refusal"] = (
            None
            if reason is None
            else f"needs Hamilton's equations as elementary operations: {reason}"
        )
    reason = cache["taylor refusal"]
    return None if reason is None else f"{stepper.name} {reason}"


def _taylor_coef(stepper, compiled, t0, y0, compensated):
    """The width of the coefficient function's ``out`` and the Kahan switch (the runner
    appends the order and the longest step)."""
    return (int(compiled.taylor().width), bool(compensated))


def _taylor_tol(compiled, stepper, t0, y0, t_end, probe_start=None):
    """Machine epsilon, or the tolerance the measured automatic choice gave taylor for
    this very run (``measured.chosen_tolerance``: the same compiled system, start and
    end; it takes a looser one only where that is priced well below)."""
    from systems.integrators.measured import chosen_tolerance

    chosen = chosen_tolerance(compiled, t0, y0, t_end)
    return float(np.finfo(float).eps) if chosen is None else chosen


def _adaptive_tol(compiled, stepper, t0, y0, t_end, probe_start=None):
    return stepsize.STIFF_TOL if stepper.stiff else stepsize.DEFAULT_TOL


FAMILIES: dict[str, Family] = {
    f.name: f
    for f in (
        Family(
            name="runge_kutta",
            description="explicit Runge-Kutta, fixed step: not symplectic (for teaching)",
            kernel="erk",
            setting="dt",
            runner=runners.FixedStepRunner,
            coefficients=_explicit_coef,
            default_setting=stepsize.default_step,
            applies=_applies_always,
            ensemble=True,
            teaching=True,
        ),
        Family(
            name="composition",
            description="explicit symplectic splitting of H = T(p) + V(q, t)",
            kernel="compose",
            setting="dt",
            runner=runners.FixedStepRunner,
            coefficients=_composition_coef,
            default_setting=stepsize.default_step,
            applies=_splitting_applies,
            wants=frozenset({"separable"}),
            functions=("grad_kinetic", "grad_potential"),
            fused=("composef", ("grad_potential", "compose_stages")),
            symplectic=True,
            needs_separable=True,
            ensemble=True,
        ),
        Family(
            name="gauss",
            description="implicit symplectic Gauss-Legendre collocation, any H and effects",
            kernel="gauss",
            setting="dt",
            runner=runners.FixedStepRunner,
            coefficients=_gauss_coef,
            default_setting=stepsize.default_step,
            applies=_applies_always,
            symplectic=True,
            ensemble=True,
        ),
        Family(
            name="logh",
            description="logarithmic-Hamiltonian time-transformed splitting (Mikkola-Tanikawa)",
            kernel="logh",
            setting="ds",
            runner=runners.TimeTransformedRunner,
            coefficients=_logh_coef,
            default_setting=stepsize.fictitious_step,
            applies=_logh_applies,
            wants=frozenset({"separable", "hamiltonian"}),
            functions=("kinetic", "potential", "grad_kinetic", "grad_potential"),
            symplectic=True,
            needs_separable=True,
            time_transformed=True,
        ),
        Family(
            name="gauss_tt",
            description="Gauss-Legendre on the Sundman-transformed system (symmetric)",
            kernel="gauss_tt",
            setting="ds",
            runner=runners.TimeTransformedRunner,
            coefficients=_gauss_tt_coef,
            default_setting=stepsize.time_transformed_step,
            applies=_applies_always,
            time_transformed=True,
        ),
        Family(
            name="dop853",
            description="compiled adaptive Runge-Kutta",
            kernel="dop853",
            setting="tol",
            runner=runners.AdaptiveRunner,
            coefficients=_dop853_coef,
            default_setting=_adaptive_tol,
            applies=_applies_always,
            adaptive=True,
        ),
        Family(
            name="taylor",
            description="Taylor series of adaptive order from the derivation (Jorba-Zou): "
            "machine precision by default, dense output from the series",
            kernel="taylor",
            setting="tol",
            runner=runners.TaylorRunner,
            coefficients=_taylor_coef,
            default_setting=_taylor_tol,
            applies=_taylor_applies,
            functions=("taylor_coefficients",),
            adaptive=True,
            adaptive_ensemble=True,
            batch=("taylor_batch_parallel", "taylor_batch"),
        ),
        Family(
            name="constrained",
            description="adaptive DOP853 on the equations with multipliers, projected onto "
            "the constraints after every step; impacts and contacts of unilateral ones "
            "located and applied",
            kernel="cdop853",
            setting="tol",
            runner=runners.AdaptiveRunner,
            coefficients=_constrained_dop853_coef,
            default_setting=_adaptive_tol,
            applies=_applies_always,
            functions=CONSTRAINED_FUNCTIONS,
            adaptive=True,
            constrained=True,
        ),
        Family(
            name="constrained_fixed",
            description="classical RK4 on the equations with multipliers, projected onto "
            "the holonomic and nonholonomic constraints after every step",
            kernel="cerk",
            setting="dt",
            runner=runners.FixedStepRunner,
            coefficients=_constrained_rk4_coef,
            default_setting=stepsize.default_step,
            applies=_fixed_step_constraints_apply,
            functions=CONSTRAINED_FUNCTIONS,
            constrained=True,
        ),
        Family(
            name="scipy",
            description="scipy's implicit solvers for stiff systems",
            kernel=None,
            setting="tol",
            runner=runners.ScipyRunner,
            coefficients=None,
            default_setting=_adaptive_tol,
            applies=_applies_always,
            functions=(),
            adaptive=True,
        ),
    )
}


def _method(name, order, family, description, **kw) -> Stepper:
    return Stepper(name=name, order=order, family=FAMILIES[family], description=description, **kw)


STEPPERS: dict[str, Stepper] = {
    s.name: s
    for s in (
        _method("euler", 1, "runge_kutta", "explicit Euler (first order, not symplectic)"),
        _method("rk4", 4, "runge_kutta", "classical 4th-order Runge-Kutta (not symplectic)"),
        _method(
            "leapfrog",
            2,
            "composition",
            "Störmer-Verlet (kick-drift-kick) leapfrog",
            weights=LEAPFROG,
        ),
        _method(
            "yoshida4",
            4,
            "composition",
            "Yoshida/Suzuki triple-jump leapfrog composition",
            weights=TRIPLE_JUMP,
        ),
        _method("yoshida6", 6, "composition", "Yoshida 7-stage composition (A)", weights=YOSHIDA6),
        _method("yoshida8", 8, "composition", "Yoshida 15-stage composition (D)", weights=YOSHIDA8),
        _method("implicit_midpoint", 2, "gauss", "implicit midpoint rule", stages=1),
        _method("gauss_legendre4", 4, "gauss", "2-stage Gauss-Legendre collocation", stages=2),
        _method("gauss_legendre6", 6, "gauss", "3-stage Gauss-Legendre collocation", stages=3),
        _method(
            "logh_leapfrog",
            2,
            "logh",
            "logarithmic-Hamiltonian time-transformed leapfrog (Mikkola-Tanikawa)",
            weights=LEAPFROG,
            finisher="yoshida8",
        ),
        _method(
            "logh_yoshida4",
            4,
            "logh",
            "logarithmic-Hamiltonian leapfrog, triple jump",
            weights=TRIPLE_JUMP,
            finisher="yoshida8",
        ),
        _method(
            "logh_yoshida6",
            6,
            "logh",
            "logarithmic-Hamiltonian leapfrog, Yoshida order 6",
            weights=YOSHIDA6,
            finisher="yoshida8",
        ),
        _method(
            "logh_yoshida8",
            8,
            "logh",
            "logarithmic-Hamiltonian leapfrog, Yoshida order 8",
            weights=YOSHIDA8,
            finisher="yoshida8",
        ),
        _method(
            "gauss_legendre4_tt",
            4,
            "gauss_tt",
            "2-stage Gauss-Legendre on the Sundman-transformed system (steps follow |dy/dt|)",
            stages=2,
            finisher="gauss_legendre4",
        ),
        _method(
            "gauss_legendre6_tt",
            6,
            "gauss_tt",
            "3-stage Gauss-Legendre on the Sundman-transformed system (steps follow |dy/dt|)",
            stages=3,
            finisher="gauss_legendre6",
        ),
        _method("dop853", 8, "dop853", "compiled adaptive Dormand-Prince 8(5,3)"),
        _method(
            "taylor",
            20,
            "taylor",
            "Taylor series, order from the tolerance (20 at the default, machine epsilon), "
            "step from the last two coefficients (Jorba-Zou)",
        ),
        _method(
            "constrained_dop853",
            8,
            "constrained",
            "adaptive Dormand-Prince 8(5,3) with projection onto the constraints and "
            "located impacts",
        ),
        _method(
            "constrained_rk4",
            4,
            "constrained_fixed",
            "classical RK4 with projection onto the holonomic and nonholonomic constraints",
        ),
        _method("radau", 5, "scipy", "scipy Radau IIA (implicit, stiff)", stiff=True),
        _method("bdf", 5, "scipy", "scipy BDF (implicit multistep, stiff)", stiff=True),
        _method("lsoda", 12, "scipy", "scipy LSODA (switches stiff/non-stiff)", stiff=True),
    )
}


def get_stepper(name: str) -> Stepper:
    """The method called ``name``; ``KeyError`` lists the known names."""
    try:
        return STEPPERS[name]
    except KeyError:
        known = ", ".join(STEPPERS)
        raise KeyError(f"unknown method {name!r}; choose from {known}") from None


def applicable(mechanics) -> dict[str, str | None]:
    """Every method by name -> None if it applies to ``mechanics``, else the reason."""
    return {name: stepper.applies_to(mechanics) for name, stepper in STEPPERS.items()}


def make_runner(
    compiled, stepper: Stepper, y0, t0, t_end, value, section, compensated=True, *,
    max_step: float = math.inf,
):  # fmt: skip
    """The runner of ``stepper``'s family for one trajectory.

    ``value`` is the step or tolerance (None: the family's default rule); ``max_step``
    bounds the steps of an adaptive family (fixed steps are chosen whole).
    """
    if value is None:
        value = stepper.default_setting(compiled, t0, y0, t_end)
    finisher = STEPPERS[stepper.finisher] if stepper.finisher else None
    extra = {"max_step": max_step} if stepper.family.adaptive else {}
    return stepper.family.runner(
        compiled, stepper, y0, t0, t_end, value, section, compensated, finisher, **extra
    )
