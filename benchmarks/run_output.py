"""`run --json` against its own integration (issue 23, item 4): the rows at the requested
times cost little beside the steps.

On the warm double pendulum (its default method and step, t_end from the scene, the
default 10 000 output times), in one process, best of ``REPEATS``:

- the integration alone: the same ``Run`` (its default step chosen as the command
  chooses it, by a short probe run) advanced to the end, no output times; and, for
  reading, its steps alone (the step given) and the same steps through the ``Sampler``
  with the command's 10 000 times;
- ``python main.py run double_pendulum --json`` called in-process: its ``wall_s`` (the
  run, the rows at exactly the requested times from the compiled loop, H and the
  velocities at them), without the scene's preparation (``prepare_s``: derivation and
  kernels from the caches, the same with or without output).

Target: ``wall_s`` within 1.5x of the integration time. Met while the double pendulum's
default was gauss_legendre6 (14 310 steps: 1.07-1.23x). With the measured choice's
dop853 at tol 1e-12 (1 794 steps, 2.7 ms) it is missed: about 4x (12 ms) while each of the
10 000 rows cost a shortened DOP853 step (11 evaluations), 2.0x (5.4 ms) with DOP853's
dense output (``kernels.dop853_sample``): three more stages and the dense coefficients
for each step that holds rows (1.2 ms), a polynomial per row (0.4 ms); 1.47-1.6x (4.8 ms
at load 2-3) once the loop allocated nothing and inlined its samples (a row 94 -> 14 ns),
and the command computed H at the rows once and the velocities at the last row only
(no --out); the taylor rows two at a time and the answering loop inlined into the
driver's: 0.62 -> 0.37 ms over the steps alone (thread CPU), 1.43-1.49x at load 5.7.
H at the rows over vectors of four rows with glibc's libmvec cut its 0.34 ms to 0.08,
but loading that code cost 1.4-2 ms a process (20-130 ms to compile it first): a loss
for one run, so not kept. With the measured choice's taylor at eps (1 086 steps, 1.3-1.6
ms) it is 1.42-1.52x (six runs, session 24): of the 0.7 ms more, H at the 10 001 rows
0.31 ms (its three cosines alone 0.25 ms: the energy check, not the output), the rows
in the driver 0.25 ms (24 ns a row at order 20), the sampler's Python 0.1 ms. Thirty
repeats instead of five did not steady it: the spread is between processes. With H over
the rows written into the scene's own LLVM module, eight rows at a time with libmvec
(``systems.llvm_kernels._RowsWriter``: 0.31 -> 0.08 ms, nothing more to load but the
library, 0.2 ms), 1.23-1.36x (session 25). The
drivers are warmed first in a child process
(``warm_drivers``: about a minute on an empty cache, a second otherwise), as ``python
main.py warm`` does once per installation; ``PHASE_EXPLORER_CACHE`` chooses the cache.
Timings on a shared machine vary: read the numbers, not only PASS.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import time

import numpy as np
from _common import report, warm_drivers

SCENE = "double_pendulum"
REPEATS = 5


def main() -> bool:
    from explorer.cli import main as cli
    from explorer.commands.run_cmd import DEFAULT_SAMPLES, prepare
    from systems.simulation import Run, Sampler, precompile

    print("run --json against its integration")
    warm_drivers()

    def command() -> dict:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            status = cli(["run", SCENE, "--json"])
        assert status == 0, out.getvalue()
        return json.loads(out.getvalue())

    first = command()  # loads the scene's kernels and the driver
    method, setting, t_end = first["method"], first["setting"], first["t_end"]
    times = np.linspace(0.0, t_end, DEFAULT_SAMPLES + 1)

    def integrate(sampled: bool, chosen: bool) -> float:
        """The command's run without its output (``sampled``: with it, through the same
        ``Sampler``); ``chosen``: the default step chosen here (a fresh system, as the
        command's, so its probe runs again), else given."""
        compiled = prepare(SCENE, method)[4]
        # as the command's preparation does: the method's loop and the system functions
        # it calls (taylor's coefficient function) loaded before the clock starts
        precompile(compiled, method, compiled.initial_state())
        start = time.perf_counter()
        given = {} if chosen else setting
        run = Run(
            compiled, method=method, y0=compiled.initial_state(), t_end=t_end,
            diagnostics=("H",), **given,
        )  # fmt: skip
        assert run.setting_value == next(iter(setting.values()))
        if sampled:
            for _ in Sampler(run, times).chunks():
                pass
        else:
            while not run.finished:
                run.advance(0.25)
        assert run.finished
        return time.perf_counter() - start

    integration = min(integrate(False, True) for _ in range(REPEATS))
    stepping = min(integrate(False, False) for _ in range(REPEATS))
    sampled = min(integrate(True, False) for _ in range(REPEATS))
    runs = [command() for _ in range(REPEATS)]
    wall = min(r["wall_s"] for r in runs)
    print(f"  {SCENE}: {method} {setting}, t_end {t_end:g}, {runs[0]['steps']} steps")
    print(
        f"  integration {integration * 1e3:.1f} ms (of which the steps {stepping * 1e3:.1f} ms,"
        f" the rest choosing the step); run --json wall_s {wall * 1e3:.1f} ms"
    )
    print(
        f"  the steps with the {DEFAULT_SAMPLES} rows at exact times (Sampler) "
        f"{sampled * 1e3:.1f} ms: {sampled / stepping:.2f}x the steps alone"
    )
    ratio = wall / integration if integration > 0 else math.inf
    return report("run --json wall_s / integration time", ratio, "<= 1.5", ratio <= 1.5)


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
