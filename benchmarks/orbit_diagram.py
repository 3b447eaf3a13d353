"""Orbit diagrams (``systems.chaos.bifurcation``): taylor in SIMD batches against the fixed
step methods, at matched accuracy of the samples, on the catalogue's periodically driven
scenes, in one run.

    python benchmarks/orbit_diagram.py [SCENE ...]

For each scene a diagram of ``VALUES`` values of one parameter (``SCENES``: a range
where the orbits are regular, so that an error is the method's, not chaos amplifying
round-off), every orbit from the scene's start (the driven damped pendulum's from
theta = -pi/2, at rest), a transient and ``SAMPLES`` samples:

- *reference*: taylor at tolerance ``REFERENCE_TOL`` (below machine epsilon: the state
  and the series' first orders in double-double), checked against the fixed-step method
  at ``CHECK_STEPS`` steps a period (their difference is printed);
- *error* of a diagram: the largest difference of its samples from the reference's,
  each state variable relative to max(1, |reference|), an angle's modulo 2 pi;
- the scene's default fixed-step method (``maps.default_map_method``) at
  ``bifurcation.PER_PERIOD`` steps a period, taylor at machine epsilon (the default
  tolerance), and taylor at the loosest of ``TOLERANCES`` whose error is at most the
  fixed-step one's (matched accuracy);
- *time*: the whole diagram (``orbit_diagram``, all cores), each kernel compiled and
  run once first, then ``REPEAT`` runs of each, interleaved; medians, and their ratios
  to the fixed-step method's (below 1: taylor faster). The load average is printed:
  on a shared machine only the ratios mean something.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import _common  # noqa: E402, F401  (the repository on the path)

VALUES = 32
SAMPLES = 32
REPEAT = 5
REFERENCE_TOL = 1e-16
CHECK_STEPS = 6400
TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)

SCENES = {
    # scene: (parameter, low, high, transient periods, start or None for the scene's)
    "driven_damped_pendulum": ("A", 1.0, 1.08, 300, (-math.pi / 2, 0.0)),
    "kapitza_pendulum": ("a", 0.08, 0.12, 40, None),
    "mathieu_oscillator": ("epsilon", 0.1, 0.3, 40, None),
    "variable_length_pendulum": ("a", 0.05, 0.1, 40, None),
}


def _error(diagram, reference, angles) -> float:
    """The largest difference of ``diagram``'s samples from ``reference``'s (rows both
    completed), relative to max(1, |reference|) per variable, angles modulo 2 pi."""
    rows = (diagram.status == 0) & (reference.status == 0)
    gap = diagram.samples[rows] - reference.samples[rows]
    for i in angles:
        gap[..., i] = np.pi - np.mod(np.pi - gap[..., i], 2 * np.pi)
    scale = np.maximum(1.0, np.abs(reference.samples[rows]))
    return float(np.max(np.abs(gap) / scale)) if rows.any() else math.nan


def _timed(kernel, values, y0) -> tuple[float, object]:
    from systems.chaos import bifurcation as bf

    start = time.perf_counter()
    diagram = bf.orbit_diagram(kernel, values, y0=y0)
    return time.perf_counter() - start, diagram


def compare(name: str) -> dict:
    """One scene's row: errors, medians and ratios (see the module)."""
    from systems.angles import angle_coordinates
    from systems.chaos import bifurcation as bf
    from systems.chaos.maps import default_map_method
    from systems.compiled import compile_system
    from systems.integrators.registry import STEPPERS
    from systems.mechanics import derive
    from systems.scene import load_scene

    parameter, low, high, transient, start = SCENES[name]
    mechanics = derive(load_scene(name))
    fixed = default_map_method(mechanics)
    compiled = compile_system(mechanics, STEPPERS[fixed].wants | {"rhs", "hamiltonian"})
    y0 = compiled.initial_state() if start is None else np.array(start, dtype=float)
    angles = [
        i for i, q in enumerate(mechanics.scene.coordinates) if q in angle_coordinates(mechanics)
    ]
    values = np.linspace(low, high, VALUES)
    T = bf.drive_period(compiled)

    def kernel(method, **options):
        return bf.strobe_kernel(
            compiled, parameter, transient=transient * T, samples=SAMPLES, method=method,
            **options,
        )  # fmt: skip

    reference = _timed(kernel("taylor", tol=REFERENCE_TOL), values, y0)[1]
    check = _timed(kernel(fixed, per_period=CHECK_STEPS), values, y0)[1]
    kernels = {f"{fixed}/{bf.PER_PERIOD}": kernel(fixed), "taylor eps": kernel("taylor")}
    errors = {
        label: _error(_timed(k, values, y0)[1], reference, angles) for label, k in kernels.items()
    }
    target = errors[f"{fixed}/{bf.PER_PERIOD}"]
    for tol in TOLERANCES:  # the loosest first
        k = kernel("taylor", tol=tol)
        error = _error(_timed(k, values, y0)[1], reference, angles)
        if error <= target:
            kernels[f"taylor {tol:g}"], errors[f"taylor {tol:g}"] = k, error
            break
    times: dict[str, list[float]] = {label: [] for label in kernels}
    for _ in range(REPEAT):
        for label, k in kernels.items():
            times[label].append(_timed(k, values, y0)[0])
    medians = {label: statistics.median(t) for label, t in times.items()}
    base = medians[f"{fixed}/{bf.PER_PERIOD}"]
    return {
        "scene": name,
        "check": _error(check, reference, angles),
        "rows": [
            (label, errors[label], medians[label], medians[label] / base) for label in kernels
        ],
        "fixed": fixed,
    }


def main(names: list[str]) -> None:
    print(f"load before: {os.getloadavg()[0]:.2f}")
    for name in names or list(SCENES):
        row = compare(name)
        parameter, low, high, transient, _ = SCENES[name]
        print(
            f"\n{name}: {parameter} in [{low:g}, {high:g}], {VALUES} values, {transient} + "
            f"{SAMPLES} periods; reference taylor {REFERENCE_TOL:g}, "
            f"{row['fixed']}/{CHECK_STEPS} differs by {row['check']:.2g}"
        )
        print(f"  {'method':<16} {'error':>9} {'median s':>9} {'ratio':>6}")
        for label, error, median, ratio in row["rows"]:
            print(f"  {label:<16} {error:9.2g} {median:9.4f} {ratio:6.2f}")
    print(f"\nload after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main(sys.argv[1:])
