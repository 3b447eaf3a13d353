"""Steps per second of the compiled loops, and the ensemble's use of both cores.

Targets (issue 3): pendulum leapfrog >= 2e7 steps/s for one trajectory; double pendulum
with Gauss-Legendre 4 >= 5e5 steps/s; an ensemble of 1000 pendulums uses both cores.

Issue 23: steps/s per family against the inlined kernels, no family below 0.85x. Until
ecd846c numba compiled each method's stepping loop per scene with the system functions
inlined; since then the loops are compiled once and call the scene's functions through
function pointers. ``compare`` extracts ``INLINED`` (ecd846c^, ``git archive``) into a
temporary directory and runs the same small script (``CHILD``) in two child processes,
one in that tree with a cache of its own, one in this tree with the environment's
cache: each derives the scene, builds its ``Run``'s runner (``make_runner``, the same API
at both commits) and runs a few steps, which compiles the old loop (1-6 s a scene and
family) or loads the new one; then each timed call is a new runner from the scene's start
(built outside the clock) and one call of its compiled loop, ``runner.advance(steps,
64)``: one trajectory, fixed steps, 64 states kept (so the same output stride), no
stream, no interpreted twin, no Python between steps. ``steps`` is the same in both trees
and makes the faster one take about ``SECONDS``; best of ``--rounds`` (5) calls per tree,
the trees alternating, which one goes first alternating too, one process working at a
time. Both must end on the same state (the 'end state' column: bitwise in every row
today). Rows: families present at both commits on representative scenes; taylor came
after ecd846c (no row). Skipped, not failed, without git or without that commit.

2026-11-29, two-core AMD EPYC VM, load average 1.1-1.5 before each run, after the fused
composition loops (``composef``, below): ``python benchmarks/throughput.py`` once, and the
composition rows again with ``--only leapfrog`` and ``--only yoshida4/`` (``--rounds 3``);
the rates are the full run's, the ratios' range both:

    family             method              scene               inlined/s  now/s    ratio
    composition        leapfrog            simple_pendulum     3.66e7     4.05e7   1.11
    composition        yoshida4            simple_pendulum     1.44e7     1.63e7   1.12-1.13
    composition        yoshida4            henon_heiles        1.99e7     1.97e7   0.99-1.00
    runge_kutta        rk4                 simple_pendulum     1.03e7     1.06e7   1.03
    runge_kutta        rk4                 double_pendulum     4.13e6     4.11e6   1.00
    gauss              gauss_legendre4     double_pendulum     7.26e5     8.29e5   1.14
    dop853 (tol 1e-10) dop853              double_pendulum     8.62e5     8.95e5   1.04
    logh               logh_yoshida4       kepler_cartesian    6.72e6     5.88e6   0.88
    gauss_tt           gauss_legendre4_tt  kepler_cartesian    7.93e5     9.39e5   1.18
    constrained        constrained_dop853  cartesian_pendulum  4.49e5     4.41e5   0.98
    constrained        constrained_dop853  rolling_disk        2.82e5     2.47e5   0.88
    constrained_fixed  constrained_rk4     cartesian_pendulum  1.06e6     1.14e6   1.08

The rolling disk's constrained_dop853 measured 0.83-0.93x over six runs that day, at the
line. Its saddle-point solve (``c_solve``, m = 6) took 168 ns with m known at run time,
134 with m a constant: ``c_lambda`` now solves m = 2..6 with m a constant (``c_solve``
inlined, LLVM unrolls it), as the kernels inlined per scene had it. Then, with
``--only constrained --rounds 5`` twice: cartesian_pendulum 4.79e5 -> 4.89e5 steps/s
(1.02x; 0.86-0.93x before), rolling_disk 2.94e5 -> 2.84e5 (0.97-1.00x), constrained_rk4
1.12-1.20x; the same end states, bitwise. It costs the rolling disk's reopen 5 ms of
loading (0.029 -> 0.035 s, target 0.05).

Before them (the former table's three runs, and one more under load the same day):
leapfrog on the simple pendulum 0.78-0.81x (27.5 -> 34.4 ns a step), yoshida4
0.74-0.76x (69 -> 93 ns), on Henon-Heiles 0.84-0.86x; the other rows as above within a
few per cent (their code did not change). The loss was a cost
per call of the scene's functions, 4-5 ns on the pendulum whichever function is called:
compose_step's body in a loop of its own, the same numba-compiled grad_kinetic and
grad_potential called directly (numba globals, inlined by LLVM: ecd846c^'s way) or through
their function pointers, takes 24.3 ns against 34.7 a leapfrog step, 61.8 against 93.2 a
yoshida4 step; Henon-Heiles's yoshida4 step 42.6 against 57.4 ns (2.5 ns a call). Each
indirect call pushes numba's array structures (seven words each) on the stack, tests the
pointer or the returned status, and afterwards reloads y, its Kahan terms and the result
from memory, which the inlined step need not; passing data pointers instead made no
difference with two calls a stage (34.1 against 34.7 ns): the call that cannot be
inlined is the cost. The remedy: the LLVM backend writes the scene's ``compose_stages``,
the step's whole stage loop with both gradients inline (``systems.llvm_kernels``), and a
single trajectory's runner takes the fused loops ``composef_*`` that call it once a step,
bitwise the same states (the 'end state' column; ``tests/systems/integrators/
test_fused_compose.py``). Its arrays go as data addresses: seven array structures by
value (392 bytes a call) made the fused leapfrog step slower than two calls (37.9
against 34.4 ns); as addresses 24.7 ns, yoshida4 61.8 (thread CPU, 2e6 and 1e6 steps,
best of 5). Only for small gradients (``STAGES_MAX_INSTRUCTIONS``: a 32-particle FPU
chain's fused steps were slower). The other families do more between calls (a tableau's
stage sums, the collocation's iterations, DOP853's error norm, the projections) and are
within noise of the inlined kernels or faster: the call's cost there is small and was
repaid by later work on the loops (allocation-free, no reference counting, steps
inlined: 89cd12c, rk4 9.5e6 -> 1.03e7 steps/s; the constrained loops in 0877b17).

Read the numbers, not only PASS: the rows within a few per cent of 0.85 (logh, the
constrained ones) pass or miss with the machine's load; the ``cpu`` column is
the same ratio from the thread's CPU time, a check that preemption did not decide it.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _common import ROOT, best_time, cache_env, compiled_scene, report

INLINED = "ecd846c^"
"""The last commit whose loops numba compiled per scene with the system inlined (the next
one, ecd846c, made the drivers take the scene's functions as first-class functions)."""
RATIO_TARGET = 0.85
"""Issue 23: no family slower than this fraction of the inlined kernels' steps/s."""
SECONDS = 0.4
"""Length of one timed call of a loop, at the faster of the two trees."""


@dataclass(frozen=True)
class Case:
    family: str
    method: str
    scene: str
    value: float  # dt, ds or tol

    @property
    def key(self) -> str:
        return f"{self.method}/{self.scene}"


# Families present at both commits, on representative systems (taylor came later).
CASES = (
    Case("composition", "leapfrog", "simple_pendulum", 1e-3),
    Case("composition", "yoshida4", "simple_pendulum", 1e-3),
    Case("composition", "yoshida4", "henon_heiles", 1e-2),
    Case("runge_kutta", "rk4", "simple_pendulum", 1e-3),
    Case("runge_kutta", "rk4", "double_pendulum", 1e-3),
    Case("gauss", "gauss_legendre4", "double_pendulum", 1e-3),
    Case("dop853", "dop853", "double_pendulum", 1e-10),
    Case("logh", "logh_yoshida4", "kepler_cartesian", 1e-3),
    Case("gauss_tt", "gauss_legendre4_tt", "kepler_cartesian", 1e-3),
    Case("constrained", "constrained_dop853", "cartesian_pendulum", 1e-10),
    Case("constrained", "constrained_dop853", "rolling_disk", 1e-10),
    Case("constrained_fixed", "constrained_rk4", "cartesian_pendulum", 1e-3),
)

# One trajectory's loop in a child process, driven over stdin/stdout one request at a time,
# the same script in either tree (the runners' API is the same at both commits):
# prepare (derive, compile the scene and run a few steps: numba compiles or loads the
# loop), then time: a new runner from the scene's start, outside the clock, and one call of
# its compiled loop for ``steps`` steps keeping 64 states (``runner.advance``).
CHILD = r"""
import gc, json, math, os, sys, time
sys.path.insert(0, os.getcwd())
reply = os.fdopen(os.dup(1), "w", buffering=1)
os.dup2(2, 1)  # whatever the code prints goes to stderr
import numpy as np
from systems.compiled import compile_system
from systems.integrators import get_stepper
from systems.integrators.registry import make_runner
from systems.mechanics import derive
from systems.scene import load_scene
from systems.simulation import required_wants

cases = {}
for line in sys.stdin:
    request = json.loads(line)
    if request["op"] == "quit":
        break
    key = request["key"]
    if request["op"] == "prepare":
        start = time.perf_counter()
        wants = required_wants(request["method"]) | {"hamiltonian"}
        compiled = compile_system(derive(load_scene(request["scene"])), wants)
        stepper = get_stepper(request["method"])
        case = cases[key] = (compiled, stepper, compiled.initial_state(0.0), request["value"])
        built = time.perf_counter()
        make_runner(compiled, stepper, case[2], 0.0, math.inf, case[3], None).advance(4, 64)
        reply.write(json.dumps({"build": built - start,
                                "loop": time.perf_counter() - built}) + "\n")
        continue
    compiled, stepper, y0, value = cases[key]
    runner = make_runner(compiled, stepper, y0, 0.0, math.inf, value, None)
    gc.collect()
    gc.disable()
    start, cpu = time.perf_counter(), time.thread_time()
    out = runner.advance(request["steps"], 64)
    wall, cpu = time.perf_counter() - start, time.thread_time() - cpu
    gc.enable()
    reply.write(json.dumps({"wall": wall, "cpu": cpu, "steps": out.steps, "evals": out.evals,
                            "code": int(out.code), "t": runner.t,
                            "y": [float(v) for v in runner.y]}) + "\n")
"""


class Child:
    """A child process running ``CHILD`` in ``tree`` with the cache ``cache`` (None: the
    environment's)."""

    def __init__(self, tree: Path, cache: Path | None):
        self.stderr = tempfile.TemporaryFile()  # a file, not a pipe: never full
        self.process = subprocess.Popen(
            [sys.executable, "-c", CHILD], cwd=tree, env=cache_env(cache), text=True,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.stderr,
        )  # fmt: skip

    def ask(self, **request) -> dict:
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            self.process.kill()
            self.process.wait()
            self.stderr.seek(0)
            raise RuntimeError(self.stderr.read().decode(errors="replace")[-3000:])
        return json.loads(line)

    def close(self) -> None:
        if self.process.poll() is None:
            try:
                self.process.stdin.write('{"op": "quit"}\n')
                self.process.stdin.flush()
                self.process.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self.process.kill()
                self.process.wait()
        self.stderr.close()


def old_tree(into: Path) -> str | None:
    """Extract ``INLINED`` into ``into`` (``git archive``); the reason if it cannot."""
    if shutil.which("git") is None:
        return "git is not installed"
    try:
        archive = subprocess.run(
            ["git", "-C", str(ROOT), "archive", "--format=tar", INLINED],
            capture_output=True, check=True, timeout=120,
        )  # fmt: skip
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired, OSError) as exc:
        stderr = getattr(exc, "stderr", b"") or b""
        return f"git archive {INLINED} failed: {stderr.decode(errors='replace').strip() or exc}"
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        if hasattr(tarfile, "data_filter"):  # Python 3.11.4 on
            tar.extractall(into, filter="data")
        else:
            tar.extractall(into)
    return None


def measure(old: Child, new: Child, case: Case, rounds: int) -> dict:
    """Best steps/s of ``case`` in both trees: ``rounds`` timed calls each, alternating
    which tree goes first."""
    request = dict(key=case.key, method=case.method, scene=case.scene, value=case.value)
    prepared = {"old": old.ask(op="prepare", **request), "new": new.ask(op="prepare", **request)}
    probe = 20_000
    rates = []
    for child in (old, new):
        r = child.ask(op="time", key=case.key, steps=probe)
        rates.append(r["steps"] / r["wall"])
    steps = max(probe, math.ceil(SECONDS * max(rates)))
    best = {"old": math.inf, "new": math.inf}
    cpu = {"old": math.inf, "new": math.inf}
    last = {}
    for i in range(rounds):
        order = (("old", old), ("new", new)) if i % 2 == 0 else (("new", new), ("old", old))
        for name, child in order:
            r = child.ask(op="time", key=case.key, steps=steps)
            best[name] = min(best[name], r["wall"])
            cpu[name] = min(cpu[name], r["cpu"])
            last[name] = r
    same = last["old"]["steps"] == last["new"]["steps"]
    y_old, y_new = np.array(last["old"]["y"]), np.array(last["new"]["y"])
    scale = max(1.0, float(np.max(np.abs(y_old))))
    return {
        "steps": last["new"]["steps"],
        "old": last["old"]["steps"] / best["old"],
        "new": last["new"]["steps"] / best["new"],
        "old_cpu": last["old"]["steps"] / cpu["old"],
        "new_cpu": last["new"]["steps"] / cpu["new"],
        "same_steps": same,
        "state_gap": float(np.max(np.abs(y_old - y_new))) / scale,
        "evals": (last["old"]["evals"], last["new"]["evals"]),
        "compile": prepared["old"]["loop"] + prepared["old"]["build"],
    }


def compare(rounds: int = 5, cases=CASES) -> bool:
    """steps/s of each case now and with the inlined kernels of ``INLINED``; one PASS/MISS
    line per case (ratio now / inlined >= ``RATIO_TARGET``). Skipped (True) when the old
    tree cannot be had."""
    print(f"  against the inlined kernels of {INLINED} (ratio = now / inlined, target >= "
          f"{RATIO_TARGET}); taylor did not exist then: no row")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="pe-inlined-") as tmp:
        tree = Path(tmp) / "tree"
        tree.mkdir()
        why = old_tree(tree)
        if why is not None:
            print(f"  skipped: {why}")
            return True
        old = Child(tree, Path(tmp) / "cache")
        new = Child(ROOT, None)
        results = []
        try:
            for case in cases:
                print(f"  {case.method} on {case.scene}: the inlined loop compiles (seconds to "
                      "tens of seconds, once per scene and family) ...", flush=True)  # fmt: skip
                results.append((case, measure(old, new, case, rounds)))
                r = results[-1][1]
                print(f"    {r['old']:.3g} -> {r['new']:.3g} steps/s "
                      f"({r['new'] / r['old']:.2f}x; old tree's scene and loop ready in "
                      f"{r['compile']:.1f} s)", flush=True)  # fmt: skip
        except RuntimeError as exc:  # a child died: its stderr's end
            print(f"  the comparison failed at {case.key}:\n{exc}")
            results.append((case, None))
        finally:
            old.close()
            new.close()
    head = f"  {'family':<18}{'method':<20}{'scene':<19}{'steps':>10}"
    print(head + f"{'inlined/s':>11}{'now/s':>11}{'ratio':>7}{'cpu':>7}  end state")
    ok = True
    for case, r in results:
        if r is None:
            ok &= report(f"{case.method} on {case.scene}, measured", 0, "both trees", False)
            continue
        ratio, cpu = r["new"] / r["old"], r["new_cpu"] / r["old_cpu"]
        same = "bitwise" if r["state_gap"] == 0.0 else f"{r['state_gap']:.1g}"
        same = same if r["same_steps"] else "steps differ"
        print(f"  {case.family:<18}{case.method:<20}{case.scene:<19}{r['steps']:>10}"
              f"{r['old']:>11.3g}{r['new']:>11.3g}{ratio:>7.2f}{cpu:>7.2f}  {same}")  # fmt: skip
    for case, r in results:
        if r is None:
            continue
        ratio = r["new"] / r["old"]
        ok &= report(
            f"{case.method} on {case.scene}, now / inlined steps/s", ratio,
            f">= {RATIO_TARGET}", ratio >= RATIO_TARGET,
        )  # fmt: skip
    return ok


def single(compiled, method: str, steps: int, dt: float) -> float:
    from systems.simulation import stream

    def go():
        for _ in stream(compiled, method=method, dt=dt, t_end=steps * dt, block_seconds=1.0,
                        max_points=64):  # fmt: skip
            pass

    go()  # compile
    return steps / best_time(go)


def main(inlined: bool = True, rounds: int = 5) -> bool:
    import numba

    from systems.simulation import ensemble

    print("throughput")
    ok = True
    pendulum = compiled_scene("simple_pendulum", ("rhs", "hamiltonian", "separable"))
    rate = single(pendulum, "leapfrog", 20_000_000, 1e-3)
    ok &= report("pendulum leapfrog, steps/s", rate, ">= 2e7", rate >= 2e7)
    double = compiled_scene("double_pendulum")
    rate = single(double, "gauss_legendre4", 500_000, 1e-3)
    ok &= report("double pendulum gauss_legendre4, steps/s", rate, ">= 5e5", rate >= 5e5)

    Y0 = np.column_stack([np.linspace(0.1, 3.0, 1000), np.zeros(1000)])
    cores = os.cpu_count() or 1

    def run_ensemble():
        ensemble(pendulum, Y0, method="yoshida4", t_end=200.0, dt=1e-3, samples=10)

    run_ensemble()
    numba.set_num_threads(1)
    serial = best_time(run_ensemble, 2)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    parallel = best_time(run_ensemble, 2)
    speedup = serial / parallel
    steps = 1000 * 200_000 / parallel
    print(f"  ensemble of 1000 pendulums: {steps:.3g} steps/s on {numba.get_num_threads()} "
          f"threads ({cores} cores)")  # fmt: skip
    ok &= report(
        "ensemble speed-up, threads vs one", speedup, f">= {0.75 * min(cores, 2):.2g} (both cores)",
        speedup >= 0.75 * min(cores, 2),
    )  # fmt: skip
    if inlined:
        ok &= compare(rounds)
    return ok


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--no-inlined",
        action="store_true",
        help=f"skip the comparison with the inlined kernels of {INLINED}",
    )
    parser.add_argument("--rounds", type=int, default=5, help="timed calls per tree and case")
    parser.add_argument("--only", help="comparison only, of the cases whose method/scene "
                        "contains this text")  # fmt: skip
    args = parser.parse_args()
    if args.only is not None:
        chosen = tuple(c for c in CASES if args.only in c.key)
        raise SystemExit(0 if compare(args.rounds, chosen) else 1)
    raise SystemExit(0 if main(not args.no_inlined, args.rounds) else 1)
