"""The Floquet tab: constant solutions of a driven system, stability charts over two
parameters, and periodic orbits of autonomous systems."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from systems.textbook.floquet import (
    FloquetAnalysis,
    VariationalSystem,
    analyse,
    chart_rows,
    explicit_time,
)
from systems.textbook.jobs._cancel import NEVER, Cancel
from systems.textbook.jobs._run import names_of, parameters_of
from systems.textbook.periodic_orbits import PeriodicOrbit, find_periodic_orbit, guess_period

if TYPE_CHECKING:
    from systems.compiled import CompiledSystem


@dataclass(frozen=True)
class FloquetResult:
    """What the Floquet tab shows first.

    Attributes
    ----------
    driven : bool
        L (or H) depends on t explicitly: ``analysis`` holds the constant solutions.
    analysis : FloquetAnalysis or None
    names : tuple of str
    parameters : dict[str, float]
        The values the analysis used (sliders included).
    system : VariationalSystem or None
        For the chart and the periodic orbits (None where it cannot be formed).
    reason : str
        Why there is no system, else "".
    """

    driven: bool
    analysis: FloquetAnalysis | None
    names: tuple[str, ...]
    parameters: dict[str, float]
    system: VariationalSystem | None
    reason: str


def floquet(compiled: CompiledSystem, cancel: Cancel = NEVER) -> FloquetResult:
    """The Floquet analysis of the current system (constant solutions when driven)."""
    cancel.check()
    mechanics = compiled.mechanics
    parameters = parameters_of(compiled)
    names = names_of(compiled)
    if explicit_time(mechanics):
        analysis = analyse(mechanics, parameters, cancel=cancel)
        return FloquetResult(True, analysis, names, parameters, analysis.system, "")
    try:
        system = VariationalSystem.build(mechanics)
    except ValueError as exc:
        return FloquetResult(False, None, names, parameters, None, str(exc))
    return FloquetResult(False, None, names, parameters, system, "")


@dataclass(frozen=True)
class ChartBlock:
    """Rows ``first .. first + len(codes)`` of a stability chart (``floquet.chart_rows``)."""

    first: int
    codes: np.ndarray
    growth: np.ndarray


def chart_block(
    system: VariationalSystem,
    q_star: np.ndarray,
    base: dict[str, float],
    x_name: str,
    x_values: np.ndarray,
    y_name: str,
    y_values: np.ndarray,
    first: int,
    count: int,
    cancel: Cancel = NEVER,
) -> ChartBlock:
    """``count`` rows of the chart from row ``first``: one job of a chart computed in
    blocks, so the tab shows its progress and can stop between blocks."""
    rows = np.asarray(y_values)[first : first + count]
    codes, growth = chart_rows(
        system, np.asarray(q_star), base, x_name, np.asarray(x_values), y_name, rows, cancel=cancel
    )
    return ChartBlock(first, codes, growth)


def periodic_orbit_from(
    system: VariationalSystem,
    y0: np.ndarray,
    parameters: dict[str, float],
    period: float | None,
    t_max: float,
    cancel: Cancel = NEVER,
) -> PeriodicOrbit:
    """The periodic orbit of an autonomous system near ``y0`` (shooting and Newton; the
    period guessed from the first close return when ``period`` is None).

    Raises
    ------
    ValueError
        When the orbit does not come back near ``y0`` within ``t_max``.
    """
    P = system.parameter_vector(parameters)
    y0 = np.asarray(y0, dtype=float)
    if period is None:
        period = guess_period(system, y0, P, t_max, cancel=cancel)
        if period is None:
            raise ValueError(
                f"the orbit from this start does not come back near it within t = {t_max:g}: "
                "give a period guess"
            )
    return find_periodic_orbit(system, y0, P, period, autonomous=True, cancel=cancel)
