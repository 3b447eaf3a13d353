"""``load`` and ``System``: a scene, derived and compiled on demand, with the command
line's operations as methods (``run``, ``section``, ``lyapunov``, ``chaosmap``,
``bifurcation``), checked as the command line checks them (``systems.usage``)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import sympy

from phase_explorer import results
from systems.limits import DEFAULT_ENERGY_TOLERANCE, DEFAULT_MAX_STEPS
from systems.usage import UsageError

DEFAULT_SAMPLES = 1000
"""Rows ``System.run`` returns by default: the states at this many evenly spaced times
(after the start)."""
DEFAULT_LYAPUNOV_T_END = 1e4
"""``System.lyapunov``'s end time by default (as ``lyapunov``'s)."""
DEFAULT_SECTION_T_END = 500.0
"""How long ``System.section`` follows each orbit by default."""


def load(scene: str | Path) -> System:
    """A system from a catalogue name, a path to a ``.toml`` file, or TOML text.

    Parameters
    ----------
    scene : str or Path
        ``"simple_pendulum"`` (see ``catalogue()``), ``"my_system.toml"``, or the scene's
        text itself (anything with a newline or a ``[`` table).

    Raises
    ------
    systems.scene.SceneError
        (a ``ValueError``) naming the file, the field and what to fix.
    """
    from systems.scene import load_scene, parse_scene

    if isinstance(scene, str) and ("\n" in scene or scene.lstrip().startswith("[")):
        return System(parse_scene(scene, source="<text>"))
    return System(load_scene(scene))


def catalogue() -> list[str]:
    """The catalogue's scene names (``python main.py list``)."""
    from systems.scene import catalogue as entries

    return [entry.name for entry in entries()]


class System:
    """A mechanical system: its scene, derived once and compiled as each call needs.

    Build with ``load``. Values are immutable: ``with_parameters`` and ``with_initial``
    return new systems.
    """

    def __init__(self, scene) -> None:
        self.scene = scene
        self._mechanics = None

    def __repr__(self) -> str:
        return f"<System {self.name!r}: {self.title}>"

    @property
    def name(self) -> str:
        """The scene's short name (a catalogue name or a file's stem; ``""`` for text)."""
        return self.scene.name

    @property
    def title(self) -> str:
        """The scene's title."""
        return self.scene.title

    @property
    def coordinates(self) -> tuple[str, ...]:
        """The generalized coordinates' names, (n,)."""
        return tuple(self.scene.coordinates)

    @property
    def parameters(self) -> dict[str, float]:
        """Parameter name -> value."""
        return dict(self.scene.parameter_values)

    @property
    def initial(self) -> dict[str, float]:
        """The scene's initial values by name (coordinates, velocities or momenta)."""
        return dict(self.scene.initial)

    @property
    def state_names(self) -> tuple[str, ...]:
        """The 2n state variables: the coordinates, then ``p_<q>`` momenta."""
        return (*self.coordinates, *(f"p_{q}" for q in self.coordinates))

    def with_parameters(self, **values: float) -> System:
        """The same system with other parameter values (``UsageError`` for a name the
        scene does not have)."""
        unknown = sorted(set(values) - set(self.parameters))
        if unknown:
            raise UsageError(
                f"unknown parameter {', '.join(unknown)}; the scene has "
                f"{', '.join(self.parameters) or 'none'}"
            )
        return System(self.scene.with_parameters(**values))

    def with_initial(self, **values: float) -> System:
        """The same system from another start (coordinates, ``<q>_dot`` or ``p_<q>``)."""
        return System(self.scene.with_initial(**values))

    # -- derivation ------------------------------------------------------------------------

    @property
    def mechanics(self):
        """``systems.mechanics.Mechanics``, derived on first use."""
        if self._mechanics is None:
            from systems.mechanics import derive

            self._mechanics = derive(self.scene)
        return self._mechanics

    def derive(self) -> results.Derivation:
        """Lagrange's and Hamilton's equations, the momenta, H, the cyclic coordinates,
        the conserved quantities and the classification, as sympy objects.

        Raises
        ------
        systems.mechanics.DerivationError
            (a ``ValueError``) naming what cannot be derived.
        """
        from systems.display import latex_names

        m = self.mechanics
        q = self.coordinates
        names = latex_names(self.scene)
        for name in q:
            names[f"p_{name}_dot"] = f"\\dot{{p}}_{{{names[name]}}}"
        qddot = sympy.Matrix([sympy.Symbol(f"{name}_ddot", real=True) for name in q])
        lagrange = ()
        if m.mass_matrix is not None and m.forcing is not None:
            left = m.mass_matrix * qddot
            lagrange = tuple(sympy.Eq(left[i], m.forcing[i], evaluate=False) for i in range(len(q)))
        dots = [sympy.Symbol(f"{name}_dot", real=True) for name in q]
        dots += [sympy.Symbol(f"p_{name}_dot", real=True) for name in q]
        hamilton = tuple(
            sympy.Eq(lhs, rhs, evaluate=False)
            for lhs, rhs in zip(dots, m.hamilton_equations or (), strict=False)
        )
        momenta = {}
        if m.momenta is not None:
            momenta = {f"p_{name}": expr for name, expr in zip(q, m.momenta, strict=True)}
        return results.Derivation(
            title=self.title, coordinates=q, lagrangian=m.lagrangian,
            hamiltonian=m.hamiltonian, momenta=momenta, lagrange_equations=lagrange,
            hamilton_equations=hamilton, cyclic=tuple(m.cyclic), conserved=dict(m.conserved),
            classification=m.classification.as_dict(), latex_names=names, mechanics=m,
        )  # fmt: skip

    # -- a run -----------------------------------------------------------------------------

    def run(
        self,
        t_end: float | None = None,
        *,
        method: str | None = None,
        dt: float | None = None,
        tol: float | None = None,
        samples: int | None = None,
        every: float | None = None,
        start: Mapping[str, float] | None = None,
        max_steps: int = DEFAULT_MAX_STEPS,
        energy_tolerance: float | str | None = DEFAULT_ENERGY_TOLERANCE,
    ) -> results.Trajectory:
        """Integrate from the scene's start (or ``start``) to ``t_end`` (default: the
        scene's ``[view] t_end``), as ``python main.py run`` does.

        Parameters
        ----------
        t_end : float, optional
        method : str, optional
            A method name (``python main.py methods SCENE``); default: the automatic,
            measured choice.
        dt, tol : float, optional
            The step of a fixed-step method or the tolerance of an adaptive one.
        samples : int, optional
            Rows: the states at this many evenly spaced times after the start (default
            1000); or ``every`` DT.
        start : dict, optional
            Values replacing the scene's initial ones (``{"theta": 2.0}``).
        max_steps : int
            Step budget (status ``"budget"`` beyond it).
        energy_tolerance : float or "off" or None
            Stop when the relative energy error exceeds this.

        Returns
        -------
        Trajectory
            ``t`` (k,), ``y`` (k, 2n), ``qdot`` (k, n), ``H`` (k,), named ``columns``.

        Raises
        ------
        UsageError
            For an option the command line refuses, with the same message (naming the
            keyword: ``t_end`` where the command line says ``--t-end``).
        """
        from systems.simulation import Run, Sampler
        from systems.usage import check_t_end, integration_settings, prepare_run, sample_times

        if t_end is not None:
            check_t_end(t_end, "t_end")
        mechanics = self.mechanics
        given_end = t_end if t_end is not None and math.isfinite(t_end) else None
        measure = dt is None and tol is None
        method, why, compiled = prepare_run(mechanics, method, t_end=given_end, measure=measure)
        if t_end is None:
            t_end = float(self.scene.view.get("t_end", 10.0))
            check_t_end(t_end, f"the scene's [view] t_end of {t_end}")
        options = integration_settings(
            method, t_end, dt=dt, tol=tol, max_steps=max_steps,
            energy_tolerance=energy_tolerance, spell=str,
        )  # fmt: skip
        times = sample_times(
            t_end, samples=samples, every=every, default=DEFAULT_SAMPLES, spell=str
        )
        y0 = self._start(compiled, start)
        run = Run(compiled, method=method, y0=y0, t_end=t_end, diagnostics=("H",), **options)
        sampler = Sampler(run, times)
        ts, ys = [], []
        for t, y in sampler.chunks():
            ts.append(t)
            ys.append(y)
        t, y = np.concatenate(ts), np.concatenate(ys)
        with np.errstate(all="ignore"):
            H = compiled.hamiltonian(t, y)
            qdot = compiled.velocities(t, y)
        last = sampler.last if sampler.last is not None else run.stop("interrupted", "")
        status, message = last.status, last.message
        if sampler.interrupted:  # Ctrl+C (a notebook's interrupt): the rows so far
            status, message = "interrupted", f"interrupted at t = {t[-1]:.6g}"
        conserved = mechanics.classification.hamiltonian_conserved
        max_rel = None
        if conserved:
            scale = abs(H[0]) if abs(H[0]) > 1e-8 else 1.0
            max_rel = max(float(np.max(np.abs(H - H[0])) / scale), sampler.worst / scale)
        elif status == "ok":  # nothing in the run watched its answer: a finer run does
            from systems.run_check import check_final_state

            found = check_final_state(
                compiled, method, last.setting, last.setting_value, 0.0, y0,
                float(last.t[-1]), last.y[-1], max_steps=options["max_steps"],
            )  # fmt: skip
            if not found.accurate:
                status, message = "inaccurate", found.message
        scene = self.scene
        columns = ("t", *scene.coordinates, *scene.velocity_names, *scene.momentum_names, "H")
        return results.Trajectory(
            t=t, y=y, qdot=qdot, H=H, columns=columns, method=method, why=why, status=status,
            message=message, steps=int(last.steps), max_rel_energy_error=max_rel,
            title=self.title,
        )  # fmt: skip

    def _start(self, compiled, start: Mapping[str, float] | None) -> np.ndarray:
        from systems.usage import start_state

        return start_state(compiled, start, "start")

    # -- sections --------------------------------------------------------------------------

    def section(
        self,
        t_end: float = DEFAULT_SECTION_T_END,
        *,
        points: Sequence[tuple[float, float]] | None = None,
        energy: float | None = None,
        starts: Sequence[Mapping[str, float]] | None = None,
        method: str | None = None,
        dt: float | None = None,
        tol: float | None = None,
    ) -> results.Section:
        """The Poincaré section of orbits followed to ``t_end``: for two degrees of
        freedom with H conserved, crossings of the scene's section (``[view] section``,
        else an angle or the first coordinate at 0) with p_j > 0; for a periodically
        driven system, the state once per period of the drive (stroboscopic).

        Parameters
        ----------
        points : sequence of (q_i, p_i), optional
            Starts on the section itself (its ``axes``) at ``energy`` (default: the
            scene's start's), the missing momentum solved as a click on the section
            solves it. Not for a stroboscopic section.
        starts : sequence of dict, optional
            Starts as values replacing the scene's (``[{"y": 0.1}, {"y": 0.2}]``).
            Default: the scene's start alone.

        Returns
        -------
        Section
            ``t`` (k,), ``y`` (k, 2n), ``orbit`` (k,) and the crossings in its ``axes``.
        """
        from systems.chaos.bifurcation import drive_period
        from systems.simulation import Run
        from systems.usage import check_t_end, integration_settings, map_section, prepare_run

        check_t_end(t_end, "t_end")
        mechanics = self.mechanics
        method, _, compiled = prepare_run(mechanics, method, t_end=t_end, measure=False)
        options = integration_settings(
            method, t_end, dt=dt, tol=tol, max_steps=DEFAULT_MAX_STEPS,
            energy_tolerance=DEFAULT_ENERGY_TOLERANCE, spell=str,
        )  # fmt: skip
        names = self.state_names
        n = compiled.n
        period = drive_period(compiled) if mechanics.classification.time_dependent else None
        label = self.name or "the scene"
        section = None
        if period is not None:
            if points is not None or energy is not None:
                raise UsageError(
                    "a stroboscopic section has no energy: give its orbits as starts, not "
                    "points and energy"
                )
            kind, cut, run_options = "stroboscopic", f"t = {period:.6g} k", {"strobe": period}
            axes = (names[0], names[n])
        else:
            try:
                section = map_section(compiled, label, spell=str)
            except UsageError:
                raise UsageError(
                    f"{label}: a Poincaré section needs two degrees of freedom and a conserved "
                    "H, or a drive periodic in t"
                ) from None
            kind = "poincare"
            cut = f"{names[section.coordinate]} = {section.value:g}"
            run_options = {"section": (section.coordinate, section.value, 1)}
            axes = (names[section.shown], names[n + section.shown])
            if energy is not None and points is None:
                raise UsageError(
                    "energy is the energy of points on the section: give points=[(q, p), ...] "
                    "with it (starts carry their own energy)"
                )
        y0s = self._section_starts(compiled, points, energy, starts, section)
        section_energy = None
        if period is None:  # one energy when every orbit has it
            H = compiled.hamiltonian(0.0, y0s)
            if np.allclose(H, H[0], rtol=1e-9, atol=1e-12):
                section_energy = float(H[0])
        ts, ys, orbit, ended = [], [], [], []
        for k, y0 in enumerate(y0s):
            run = Run(compiled, method=method, y0=y0, t_end=t_end, **options, **run_options)
            block = None
            while block is None or not block.finished:
                block = run.advance(seconds=1.0)
                ts.append(np.asarray(block.events_t, dtype=float))
                ys.append(np.asarray(block.events_y, dtype=float).reshape(-1, 2 * n))
                orbit.append(np.full(len(block.events_t), k))
            ended.append(block.status)
        return results.Section(
            t=np.concatenate(ts), y=np.concatenate(ys), orbit=np.concatenate(orbit),
            axes=axes, names=names, kind=kind, cut=cut, energy=section_energy,
            status=tuple(ended), title=self.title,
        )  # fmt: skip

    def _section_starts(self, compiled, points, energy, starts, section) -> np.ndarray:
        """(m, 2n) starts of ``section``'s orbits."""
        from systems.section import states_on_section

        if points is not None and starts is not None:
            raise UsageError("give the orbits as points on the section or as starts, not both")
        if points is None:
            given = list(starts) if starts is not None else [None]
            return np.array([self._start(compiled, values) for values in given])
        xy = np.asarray(points, dtype=float).reshape(-1, 2)
        y0 = self._start(compiled, None)
        if energy is None:
            energy = float(compiled.hamiltonian(0.0, y0[None])[0])
        if not math.isfinite(energy):
            raise UsageError(f"energy must be a finite number, not {energy!r}")
        found = states_on_section(compiled, section, energy, xy[:, 0], xy[:, 1])
        missing = ~np.isfinite(found).all(axis=1)
        if missing.any():
            where = ", ".join(f"({a:g}, {b:g})" for a, b in xy[missing][:3])
            raise UsageError(
                f"no state on the section at energy {energy:g} at {where}: the energy cannot "
                "reach these points; give other points or another energy"
            )
        return found

    # -- chaos -----------------------------------------------------------------------------

    def lyapunov(
        self,
        t_end: float = DEFAULT_LYAPUNOV_T_END,
        *,
        method: str | None = None,
        dt: float | None = None,
        tol: float | None = None,
        start: Mapping[str, float] | None = None,
        exponents: int | None = None,
    ) -> results.Lyapunov:
        """The Lyapunov spectrum (Benettin, QR), MEGNO, SALI and GALI of the orbit from
        the scene's start (or ``start``) to ``t_end``, as ``python main.py lyapunov``.

        Returns
        -------
        Lyapunov
            ``exponents`` (k,) largest first, ``max``, ``megno``, ``verdict``, ``sali``,
            ``gali`` and the running ``history``.
        """
        from systems.chaos.lyapunov import DEFAULT_METHOD, lyapunov, megno_verdict
        from systems.chaos.variational import NotApplicable, load_tangent
        from systems.compiled import compile_system
        from systems.integrators import STEPPERS
        from systems.usage import check_lyapunov, check_lyapunov_options

        method = method or DEFAULT_METHOD
        check_lyapunov_options(method, t_end, "t_end")
        mechanics = self.mechanics
        check_lyapunov(mechanics, method, self.name or "the scene")
        compiled = compile_system(mechanics, STEPPERS[method].wants | {"hamiltonian"})
        y0 = self._start(compiled, start)
        try:
            spectrum = lyapunov(
                compiled, t_end=t_end, method=method, y0=y0, dt=dt, tol=tol,
                exponents=exponents, tangent=load_tangent(compiled),
            )  # fmt: skip
        except NotApplicable as exc:
            raise UsageError(str(exc).replace("--dt", "dt").replace("--tol", "tol")) from exc
        e = spectrum.estimate
        report = spectrum.as_json()
        return results.Lyapunov(
            exponents=np.asarray(e.exponents, dtype=float), max=float(e.exponents[0]),
            megno=float(e.megno), verdict=megno_verdict(e.megno), sali=float(e.sali),
            gali=float(e.gali), t_end=float(e.t), status=e.status, message=e.message,
            energy_error=spectrum.energy_error, history=spectrum.history, report=report,
        )  # fmt: skip

    def chaosmap(
        self,
        grid: tuple[int, int] = (100, 100),
        *,
        energy: float | None = None,
        indicator: str = "megno",
        t_end: float | None = None,
        method: str | None = None,
        dt: float | None = None,
        over: tuple[str, str] | None = None,
        ranges: Mapping[str, tuple[float, float]] | None = None,
        progress: Callable[[int, int], None] | None = None,
        dask: str | object | None = None,
    ) -> results.ChaosMap:
        """MEGNO or the maximal exponent over a grid of starts, as ``python main.py
        chaosmap``: on the Poincaré section at ``energy`` (default: the start's), or
        ``over`` two state variables with the rest of the start kept.

        Parameters
        ----------
        grid : (nx, ny)
            Starts along the x and y axes.
        ranges : dict, optional
            ``{name: (low, high)}`` of the axes (default: ``[view] ranges``, or the
            section's allowed region).
        t_end : float, optional
            How long each orbit runs (default 500; 100 where the method is implicit,
            gauss_legendre4 for a non-separable H).
        method : str, optional
            A fixed-step method with an ensemble loop (default: yoshida4 for a separable
            H, rk4 for a damped or driven system, else gauss_legendre4), or ``"taylor"``:
            Taylor series at machine epsilon, adaptive steps for each orbit, in SIMD
            batches (slower than the default step, and far more accurate).
        dt : float, optional
            The fixed step (default: 40 per fastest period); not with taylor.
        progress : callable, optional
            ``progress(done, total)`` after each chunk of orbits (a progress bar's
            update).
        dask : str or distributed.Client, optional
            Compute chunks of the starts on a Dask cluster: ``"auto"`` (a
            ``LocalCluster`` of this machine's cores, closed afterwards), a scheduler's
            address ``"tcp://HOST:PORT"``, or a ``Client`` of your own. The same numbers
            as without. Needs the extra: ``pip install -e ".[dask]"``.

        Returns
        -------
        ChaosMap
            ``megno``, ``lyapunov`` (ny, nx), ``chaotic_fraction`` with its ``threshold``.
        """
        from systems.chaos import maps
        from systems.usage import check_map_options, check_ranges, map_setup

        try:
            nx, ny = grid
        except (TypeError, ValueError):
            raise UsageError(f"grid is (nx, ny), a number of starts a side, not {grid!r}") from None
        t_end = check_map_options(nx, ny, indicator, t_end, spell=str)
        cluster = _cluster(dask)
        label = self.name or "the scene"
        compiled, _, kernel, map_grid = map_setup(
            self.mechanics, label, nx=nx, ny=ny, t_end=t_end, method=method, dt=dt, over=over,
            ranges=check_ranges(ranges or {}, spell=str), energy=energy, spell=str,
        )  # fmt: skip
        with cluster as client:
            found = maps.chaos_map(kernel, map_grid, progress=progress, client=client)
        return results.ChaosMap(
            xs=map_grid.xs, ys=map_grid.ys, axes=tuple(map_grid.names), megno=found.megno,
            lyapunov=found.lyapunov, status=found.status, indicator=indicator,
            chaotic_fraction=found.chaotic_fraction(indicator),
            threshold=found.threshold(indicator), energy=map_grid.energy,
            method=found.method, dt=found.dt, t_end=found.t_end, starts=map_grid.starts,
            title=self.title,
        )  # fmt: skip

    def bifurcation(
        self,
        parameter: str,
        values: Sequence[float] | np.ndarray,
        *,
        transient: float | None = None,
        samples: int = 64,
        method: str | None = None,
        steps_per_period: int | None = None,
        tol: float | None = None,
        start: Mapping[str, float] | None = None,
        variable: str | None = None,
        progress: Callable[[int, int], None] | None = None,
        dask: str | object | None = None,
    ) -> results.OrbitDiagram:
        """The orbit diagram of a periodically driven system over ``parameter``, as
        ``python main.py bifurcation``: for each of ``values`` (N,), the orbit from the
        scene's start (or ``start``) runs ``transient`` (default 300 periods of the
        drive), then ``samples`` periods, its state kept at each period's end.
        ``method`` taylor (the default where it applies) takes ``tol`` (default machine
        epsilon), a fixed-step method ``steps_per_period``.
        ``progress(done, total)`` is called after each chunk of values; ``dask`` as
        ``chaosmap``'s (chunks of the values on a Dask cluster).

        Returns
        -------
        OrbitDiagram
            ``samples`` (N, K, 2n), ``periods`` (N,) and the ``variable`` plotted.
        """
        from systems.chaos import bifurcation as bf
        from systems.usage import MAX_DIAGRAM_VALUES, diagram_setup

        values = np.atleast_1d(np.asarray(values, dtype=float))
        if values.ndim != 1 or not 1 <= len(values) <= MAX_DIAGRAM_VALUES:
            raise UsageError(
                f"values are from 1 to {MAX_DIAGRAM_VALUES} numbers, not an array of shape "
                f"{values.shape}"
            )
        if not np.isfinite(values).all():
            raise UsageError("values must be finite numbers")
        cluster = _cluster(dask)
        compiled, kernel, y0, variable, angles = diagram_setup(
            self.mechanics, self.name or "the scene", parameter=parameter, transient=transient,
            samples=samples, method=method, steps_per_period=steps_per_period, start=start,
            variable=variable, spell=str, tol=tol,
        )  # fmt: skip
        with cluster as client:
            diagram = bf.orbit_diagram(kernel, values, y0=y0, progress=progress, client=client)
        names = tuple(diagram.names)
        return results.OrbitDiagram(
            parameter=parameter, values=values, samples=diagram.samples, variable=variable,
            periods=bf.periods(diagram, angles=tuple(angles)), status=diagram.status,
            drive_period=bf.drive_period(compiled), names=names, method=kernel.method,
            transient_periods=kernel.transient_periods,
            wrap=names.index(variable) in angles, title=self.title,
        )  # fmt: skip


def _cluster(dask: str | object | None) -> contextlib.AbstractContextManager:
    """The ``dask`` argument as a context manager giving a ``distributed.Client`` (or
    None): an address is checked (and the extra) now, connected to on entry, closed on
    exit; a client of the caller's is used as it is and left open.

    Raises
    ------
    UsageError
        A malformed address, the extra not installed, or something else given.
    """
    from systems.chaos import distributed

    if dask is None:
        return contextlib.nullcontext(None)
    if isinstance(dask, str):
        distributed.check_address(dask, spell=str)
        distributed.require_dask(spell=str)
        return distributed.connect(dask, spell=str)
    if callable(getattr(dask, "submit", None)) and callable(getattr(dask, "scatter", None)):
        return contextlib.nullcontext(dask)
    raise UsageError(
        "dask is 'auto', a scheduler's address 'tcp://HOST:PORT' or a distributed.Client, "
        f"not {type(dask).__name__}"
    )
