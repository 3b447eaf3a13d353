"""Every catalogue scene with default settings: method, step or tolerance, energy error, time.

The defaults aim at a relative energy error of 1e-10 over each scene's run (its
[view] t_end) where H is conserved; this prints what they reach and what it costs
(wall time of the integration, step choice included). Compiling is excluded: each
scene's functions are compiled by ``compile_system`` and its method's driver compiled or
loaded (numba's cache; ``python main.py warm`` compiles them all) by a short throwaway
stream before the timed one. Target: every conservative scene at or under 1e-10.
"""

from __future__ import annotations

import time

import numpy as np
from _common import ROOT

TARGET = 1e-10


def measure(name: str) -> tuple[str, str, float, float | None, float, int]:
    from systems.compiled import compile_system
    from systems.integrators import choose_method
    from systems.mechanics import derive
    from systems.scene import load_scene
    from systems.simulation import required_wants, stream

    mechanics = derive(load_scene(name))
    method, _ = choose_method(mechanics)
    compiled = compile_system(mechanics, required_wants(method, ("H",)))
    t_end = float(mechanics.scene.view.get("t_end", 10.0))
    for _ in stream(compiled, t_end=min(t_end, 1e-3), diagnostics=("H",)):
        pass  # compile or load the method's driver
    start = time.perf_counter()
    blocks = list(stream(compiled, t_end=t_end, diagnostics=("H",), block_seconds=1.0))
    wall = time.perf_counter() - start
    last = blocks[-1]
    error = None
    if mechanics.classification.hamiltonian_conserved:
        H = np.concatenate([b.diagnostics["H"] for b in blocks])
        H0 = float(compiled.hamiltonian(0.0, compiled.initial_state()[None])[0])
        error = float(np.max(np.abs(H - H0))) / (abs(H0) if abs(H0) > 1e-8 else 1.0)
    setting = f"{last.setting}={last.setting_value:.3g}"
    return method, setting, t_end, error, wall, int(last.steps)


def main() -> bool:
    print("Catalogue scenes with default settings (energy error where H is conserved)")
    print(f"{'scene':<26} {'method':<18} {'setting':<14} {'t_end':>7} {'energy':>9} "
          f"{'wall s':>8} {'steps':>9}")  # fmt: skip
    ok = True
    for path in sorted((ROOT / "resources" / "scenes").glob("*.toml")):
        method, setting, t_end, error, wall, steps = measure(path.stem)
        shown = "-" if error is None else f"{error:9.2e}"
        if error is not None and not error <= TARGET:
            ok = False
            shown += " MISS"
        print(f"{path.stem:<26} {method:<18} {setting:<14} {t_end:7.4g} {shown:>9} "
              f"{wall:8.3f} {steps:9d}")  # fmt: skip
    print(f"target: every conservative scene <= {TARGET:g}: {'met' if ok else 'MISSED'}")
    return ok


if __name__ == "__main__":
    raise SystemExit(0 if main() else 1)
