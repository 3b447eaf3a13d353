"""The checks of what a user asks for (a method, its step or tolerance, an end time, rows,
a start), shared by the command line (``explorer.commands``) and the Python API
(``phase_explorer``), so both refuse the same things with the same sentence.

Each check names the option as the caller spells it: the command line passes
``"--t-end"``, the API ``"t_end"``; the rest of the message is the same.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING

import numpy as np

from systems.limits import MIN_T_END

if TYPE_CHECKING:
    from systems.section import Section

MAX_ROWS = 10**7
"""The most rows a run's output holds (``samples``, ``t_end / every``)."""


class UsageError(ValueError):
    """A mistake in what was asked; the message names what to fix (the command line
    prints it and exits with status 2)."""


def cli_name(keyword: str) -> str:
    """``"t_end"`` -> ``"--t-end"``: a keyword as the command line spells it."""
    return "--" + keyword.replace("_", "-")


def check_method_name(method: str) -> None:
    """``UsageError`` unless ``method`` is a registered method."""
    from systems.integrators import STEPPERS

    if method not in STEPPERS:
        raise UsageError(f"unknown method {method!r}; choose from {', '.join(STEPPERS)}")


def check_method(mechanics, method: str) -> None:
    """``UsageError`` for an unknown method or one the system does not allow (the
    registry says why)."""
    from systems.integrators import STEPPERS

    check_method_name(method)
    refusal = STEPPERS[method].applies_to(mechanics)
    if refusal is not None:
        raise UsageError(f"method {method!r} does not apply: {refusal}")


def check_t_end(t_end: float, given: str = "--t-end", alternative: str = "") -> None:
    """``UsageError`` unless ``t_end`` is a finite time of at least ``MIN_T_END``.

    ``given`` names where the time came from; ``alternative`` is added to the message
    (" (or inf, with --out and --every)").
    """
    if not (math.isfinite(t_end) and t_end > 0):
        raise UsageError(f"{given} must be a positive finite time{alternative}, not {t_end:g}")
    if t_end < MIN_T_END:
        raise UsageError(
            f"{given} must be at least {MIN_T_END:g}, not {t_end:g}: a shorter time cannot "
            "be divided into steps"
        )


def integration_settings(
    method: str,
    t_end: float,
    *,
    dt: float | None = None,
    tol: float | None = None,
    max_steps: int,
    energy_tolerance: float | str | None,
    spell: Callable[[str], str] = cli_name,
) -> dict:
    """``systems.simulation.Run`` keywords, checked against ``method`` and a run from 0 to
    ``t_end``: the setting the method takes (``dt`` or ``tol``), a positive step budget,
    and the energy guard (a number, or ``"off"``/None for none).

    ``spell`` turns a keyword into the option's name in messages (``cli_name``, or
    ``str`` for the API's keywords).

    Raises
    ------
    UsageError
    """
    from systems.integrators import get_stepper
    from systems.simulation import parse_energy_tolerance

    problem = get_stepper(method).setting_error(dt, tol, (0.0, t_end))
    if problem:
        raise UsageError(problem if spell is cli_name else _keywords(problem))
    if (
        isinstance(max_steps, bool)
        or not (isinstance(max_steps, int | np.integer))
        or (not max_steps > 0)
    ):
        raise UsageError(f"{spell('max_steps')} must be a positive whole number, not {max_steps}")
    if energy_tolerance is None:
        guard = None
    else:
        try:
            guard = parse_energy_tolerance(str(energy_tolerance))
        except ValueError as exc:
            raise UsageError(f"{spell('energy_tolerance')}: {exc}") from None
    return dict(dt=dt, tol=tol, max_steps=int(max_steps), energy_tolerance=guard)


def _keywords(text: str) -> str:
    """A registry message's ``--dt``, ``--tol`` as the API's keywords."""
    return text.replace("--dt", "dt").replace("--tol", "tol")


def sample_times(
    t_end: float,
    *,
    samples: int | None = None,
    every: float | None = None,
    default: int = 10_000,
    spell: Callable[[str], str] = cli_name,
) -> np.ndarray | Iterator[float]:
    """The simulation times whose states are written: ``samples`` evenly spaced
    (default ``default``) or one every ``every`` (endlessly, for an endless run).

    Returns
    -------
    ndarray, shape (k,)
        Ascending times from 0 to ``t_end``, or an endless iterator for ``t_end = inf``.

    Raises
    ------
    UsageError
    """
    if every is not None:
        if not (math.isfinite(every) and every > 0):
            raise UsageError(f"{spell('every')} must be a positive time, not {every}")
        if math.isinf(t_end):
            return (k * every for k in itertools.count(1))
        count = t_end / every
        if count > MAX_ROWS:
            raise UsageError(f"{spell('every')} {every:g} asks for {count:.3g} rows; at most 1e7")
        return np.append(np.arange(0.0, t_end, every), t_end)
    count = default if samples is None else samples
    if isinstance(count, bool) or not isinstance(count, int | np.integer):
        raise UsageError(f"{spell('samples')} must be a whole number of rows, not {count!r}")
    if not 1 <= count <= MAX_ROWS:
        raise UsageError(f"{spell('samples')} must be between 1 and {MAX_ROWS}, not {count}")
    return np.linspace(0.0, t_end, count + 1)


def start_state(compiled, values: Mapping[str, float] | None, option: str = "--start"):
    """The checked start (2n,): the scene's initial state with ``values`` (coordinates,
    ``<q>_dot`` velocities or ``p_<q>`` momenta) put in; None values for the scene's own.

    Raises
    ------
    UsageError
        An unknown name or a value that is not a number (naming ``option``).
    systems.mechanics.DerivationError
        A start where the equations are singular (``systems.start_check``).
    """
    from systems.start_check import check_start
    from systems.textbook.periodic_orbits import start_state as canonical

    given = None
    if values:
        for name, value in values.items():
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise UsageError(f"{option}: {value!r} is not a number (for {name})")
        try:
            given = canonical(compiled.mechanics, dict(values))
        except ValueError as exc:
            raise UsageError(f"{option}: {exc}") from None
    return check_start(compiled, given)


def check_lyapunov_options(method: str, t_end: float, given: str = "--t-end") -> None:
    """``UsageError`` unless ``t_end`` is a finite time of at least ``MIN_T_END`` and
    ``method`` a registered method (before anything is derived)."""
    if not (math.isfinite(t_end) and t_end >= MIN_T_END):
        raise UsageError(
            f"{given} must be a finite number of at least {MIN_T_END:g}, not {t_end!r}"
        )
    check_method_name(method)


def check_lyapunov(mechanics, method: str, scene: str) -> None:
    """``UsageError`` unless the Lyapunov spectrum of ``mechanics`` can be measured by
    ``method`` (``scene`` names the system in the message)."""
    from systems.chaos.lyapunov import method_refusal
    from systems.chaos.variational import refusal

    reason = refusal(mechanics)
    if reason:
        raise UsageError(f"{scene}: Lyapunov exponents are not available here: {reason}")
    reason = method_refusal(mechanics, method)
    if reason:
        raise UsageError(f"method {method!r} cannot carry the tangent vectors: {reason}")


def prepare_run(
    mechanics,
    method: str | None,
    *,
    extra_wants=("velocities",),
    t_end: float | None = None,
    measure: bool = True,
):
    """Choose a method and compile ``mechanics`` for a run: ``(method, why, compiled)``.

    ``method`` None is the automatic choice, measured on the compiled system over
    ``t_end`` (default: the scene's ``[view] t_end``; ``systems.integrators.measured``)
    when ``measure``; a method given is checked (``check_method``). The start is checked
    (``systems.start_check``).

    Raises
    ------
    UsageError
        An unknown method or one the system does not allow.
    systems.mechanics.DerivationError
        A singular start.
    """
    from systems.compiled import compile_system
    from systems.integrators import choose_method
    from systems.integrators.measured import ALTERNATIVE, measured_choice
    from systems.simulation import required_wants
    from systems.start_check import check_start

    auto, auto_why = choose_method(mechanics)
    requested = method
    if method is None:
        method, why = auto, auto_why
    else:
        check_method(mechanics, method)
        why = f"requested (the automatic choice would be {auto}: {auto_why})"
    measured = measure and requested is None
    wants = required_wants(method) | {"hamiltonian", *extra_wants}
    if measured:  # the choice is measured against DOP853 on the compiled system
        wants |= required_wants(ALTERNATIVE)
    compiled = compile_system(mechanics, wants)
    check_start(compiled)
    if measured:
        scene = mechanics.scene
        t_end = float(scene.view.get("t_end", 10.0)) if t_end is None else t_end
        method, why = measured_choice(compiled, method, why, 0.0, compiled.initial_state(), t_end)
    return method, why, compiled


# -- chaos maps and orbit diagrams ------------------------------------------------------------

MAX_MAP_POINTS = 4_000_000
"""The most starts a chaos map takes."""
MAX_DIAGRAM_VALUES = 100_000
"""The most parameter values an orbit diagram takes."""


def check_map_options(
    nx: int,
    ny: int,
    indicator: str,
    t_end: float | None,
    *,
    grid_text: str | None = None,
    spell: Callable[[str], str] = cli_name,
) -> float | None:
    """``UsageError`` for a grid, indicator or end time a chaos map cannot take, before
    anything is derived; returns the end time given, or None: the method's default
    (``maps.default_t_end``, once the method is known).

    ``grid_text`` is the grid as the user wrote it (default ``"{nx}x{ny}"``).
    """
    from systems.chaos import maps

    for size in (nx, ny):
        if isinstance(size, bool) or not isinstance(size, int | np.integer):
            raise UsageError(f"{spell('grid')} is a number of starts a side, not {size!r}")
    if nx < 2 or ny < 2 or nx * ny > MAX_MAP_POINTS:
        raise UsageError(
            f"{spell('grid')} needs at least 2 starts a side and at most {MAX_MAP_POINTS:,} in "
            f"all, not {grid_text or f'{nx}x{ny}'}"
        )
    if indicator not in maps.INDICATORS:
        raise UsageError(f"{spell('indicator')} is megno or lyapunov, not {indicator!r}")
    if t_end is None:
        return None
    if not (math.isfinite(t_end) and t_end > 0):
        raise UsageError(f"{spell('t_end')} must be a positive finite time, not {t_end!r}")
    return float(t_end)


def check_ranges(
    ranges: Mapping[str, tuple[float, float]], spell: Callable[[str], str] = cli_name
) -> dict[str, tuple[float, float]]:
    """``{name: (low, high)}`` checked: finite ends, low below high."""
    checked = {}
    for name, bounds in ranges.items():
        try:
            lo, hi = (float(v) for v in bounds)
        except (TypeError, ValueError):
            lo = hi = math.nan
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise UsageError(
                f"{spell('ranges')} takes name=low:high items, e.g. y=-0.5:0.7, not "
                f"{name}={bounds!r}"
            )
        if not lo < hi:
            raise UsageError(f"{spell('ranges')}: {name}'s low end must be below its high end")
        checked[name] = (lo, hi)
    return checked


def map_setup(
    mechanics,
    scene: str,
    *,
    nx: int,
    ny: int,
    t_end: float | None,
    method: str | None = None,
    dt: float | None = None,
    over: tuple[str, ...] | None = None,
    ranges: Mapping[str, tuple[float, float]] | None = None,
    energy: float | None = None,
    spell: Callable[[str], str] = cli_name,
):
    """Compile ``mechanics`` for a chaos map and lay out its grid: on the Poincaré
    section at ``energy`` (default the start's), or ``over`` two state variables; every
    orbit to ``t_end`` (None: ``maps.default_t_end`` of the method).

    ``scene`` names the system in messages. Returns ``(compiled, tangent, kernel, grid)``
    (``systems.chaos.maps.MapKernel``, ``MapGrid``).

    Raises
    ------
    UsageError
        Naming what to fix; ``DerivationError`` for a singular start.
    """
    from systems.chaos import maps
    from systems.chaos.variational import NotApplicable, load_tangent, refusal
    from systems.compiled import compile_system
    from systems.integrators import STEPPERS
    from systems.start_check import check_start
    from systems.view_ranges import axis_range

    ranges = dict(ranges or {})
    reason = refusal(mechanics)
    if reason:
        raise UsageError(f"{scene}: a chaos map is not available here: {reason}")
    method_ = method or maps.default_map_method(mechanics)
    wants = (STEPPERS[method_].wants if method_ in STEPPERS else frozenset()) | {"hamiltonian"}
    compiled = compile_system(mechanics, wants)
    y0 = check_start(compiled, None)
    try:
        tangent = load_tangent(compiled)
        kernel = maps.map_kernel(tangent, t_end=t_end, method=method, dt=dt)
    except NotApplicable as exc:
        raise UsageError(
            f"{scene}: {_keywords(str(exc)) if spell is not cli_name else exc}"
        ) from exc
    names = maps.state_names(mechanics)
    if over:
        if energy is not None:
            raise UsageError(
                f"{spell('energy')} sets the section's energy; a map {spell('over')} two "
                "variables has none"
            )
        over = tuple(over)
        if len(over) != 2 or any(name not in names for name in over) or over[0] == over[1]:
            raise UsageError(
                f"{spell('over')} takes two different state variables of {', '.join(names)}, "
                f"not {','.join(map(str, over))!r}"
            )
        box = tuple(
            ranges.get(name) or axis_range(mechanics.scene, name, y0[names.index(name)])
            for name in over
        )
        grid = maps.variable_grid(compiled, over, nx, ny, box, y0)
        return compiled, tangent, kernel, grid
    section = map_section(compiled, scene, spell)
    if energy is None:
        energy = float(compiled.hamiltonian(0.0, y0[None, :])[0])
    if not math.isfinite(energy):
        raise UsageError(f"{spell('energy')} must be a finite number, not {energy!r}")
    n = compiled.n
    shown = (names[section.shown], names[n + section.shown])
    unknown = set(ranges) - set(shown)
    if unknown:
        raise UsageError(
            f"{spell('ranges')}: the section's axes are {shown[0]} and {shown[1]}, "
            f"not {', '.join(sorted(unknown))}"
        )
    declared = dict(mechanics.scene.view.get("ranges", {}) or {})
    box = [
        ranges.get(name) or (tuple(map(float, declared[name])) if name in declared else None)
        for name in shown
    ]
    if None in box:
        try:
            found = maps.section_box(compiled, section, energy)
        except ValueError as exc:
            example = (
                f"{shown[0]}=a:b,{shown[1]}=c:d"
                if spell is cli_name
                else f"{{{shown[0]!r}: (a, b), {shown[1]!r}: (c, d)}}"
            )
            raise UsageError(f"{exc} ({spell('ranges')} {example})") from exc
        box = [given or guess for given, guess in zip(box, found, strict=True)]
    grid = maps.section_grid(compiled, section, energy, nx, ny, tuple(box))
    if not grid.valid.any():
        raise UsageError(
            f"no start of the grid lies on the section at energy {energy:g}: give another "
            f"{spell('energy')} or {spell('ranges')}"
        )
    return compiled, tangent, kernel, grid


def map_section(compiled, scene: str, spell: Callable[[str], str] = cli_name) -> Section:
    """The Poincaré section a map (or ``phase_explorer``'s ``section``) lies on:
    ``systems.section.Section`` of a system of two degrees of freedom with H conserved."""
    from systems.angles import angle_coordinates
    from systems.section import Section

    mechanics = compiled.mechanics
    cls = mechanics.classification
    if compiled.n != 2 or cls.time_dependent or not cls.hamiltonian_conserved:
        raise UsageError(
            f"{scene}: a map on the Poincaré section needs two degrees of freedom and a "
            f"conserved H; span two state variables with {spell('over')} NAME,NAME instead"
        )
    angles = tuple(angle_coordinates(mechanics))
    return Section.from_scene(mechanics.scene, angles, tuple(mechanics.cyclic))


def diagram_setup(
    mechanics,
    scene: str,
    *,
    parameter: str,
    transient: float | None = None,
    samples: int = 64,
    method: str | None = None,
    steps_per_period: int | None = None,
    start: Mapping[str, float] | None = None,
    variable: str | None = None,
    spell: Callable[[str], str] = cli_name,
    tol: float | None = None,
):
    """Compile ``mechanics`` for an orbit diagram over ``parameter``.

    Returns ``(compiled, kernel, y0, variable, angles)``: the strobe kernel
    (``systems.chaos.bifurcation.StrobeKernel``), the start (2n,), the state variable
    plotted (default: the momentum of a first coordinate that is an angle, else the first
    coordinate) and the state indices of the angles.

    Raises
    ------
    UsageError
        Naming what to fix.
    """
    from systems.angles import angle_coordinates
    from systems.chaos import bifurcation as bf
    from systems.chaos.maps import state_names
    from systems.compiled import compile_system
    from systems.integrators import STEPPERS

    method_ = method or bf.default_strobe_method(mechanics)
    wants = (STEPPERS[method_].wants if method_ in STEPPERS else frozenset()) | {"hamiltonian"}
    compiled = compile_system(mechanics, wants)
    y0 = start_state(compiled, start, spell("start"))
    names = state_names(mechanics)
    coordinates = mechanics.scene.coordinates
    angles = [i for i, q in enumerate(coordinates) if q in angle_coordinates(mechanics)]
    variable = variable or (names[compiled.n] if 0 in angles else names[0])
    if variable not in names:
        raise UsageError(f"{spell('variable')} is one of {', '.join(names)}, not {variable!r}")
    options = {} if steps_per_period is None else {"per_period": steps_per_period}
    if tol is not None:
        options["tol"] = tol
    if steps_per_period is not None and not 4 <= steps_per_period <= 100_000:
        raise UsageError(
            f"{spell('steps_per_period')} must be from 4 to 100000, not {steps_per_period}"
        )
    try:
        kernel = bf.strobe_kernel(
            compiled, parameter, transient=transient, samples=samples, method=method,
            **options,
        )  # fmt: skip
    except ValueError as exc:
        raise UsageError(f"{scene}: {exc}") from exc
    return compiled, kernel, y0, variable, angles


__all__ = [
    "MAX_ROWS", "UsageError", "check_lyapunov", "check_lyapunov_options", "check_method",
    "check_method_name", "check_t_end", "cli_name", "integration_settings", "sample_times",
    "start_state", "MAX_DIAGRAM_VALUES", "MAX_MAP_POINTS", "check_map_options", "check_ranges",
    "diagram_setup", "map_section", "map_setup", "prepare_run",
]  # fmt: skip
