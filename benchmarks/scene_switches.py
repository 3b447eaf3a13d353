"""A user browsing scenes fast: open a users' scene every 0.05–2.5 s, sometimes close the
window and open a new one, while builders lay out derivations and search equilibria.

Runs in a fresh process (offscreen Qt unless a display is set) and prints the longest
time the GUI thread spent in one call (an open, a close, one ``processEvents``), and
what was left at the end. Targets: no thread of the window left and the import lock free
three seconds after the last window closed (an asynchronous exception that landed inside
an import once left the lock held for ever and hung every later import), and no call of
the GUI thread over 5 s. ``SWITCHES`` and the seed are arguments: ``python
scene_switches.py 80 7``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from _common import ROOT

SWITCHES = 40
SEED = 1
STALL_TARGET = 5.0

CODE = """
import _imp, json, random, sys, threading, time
from pathlib import Path
from explorer.app import application
from explorer.main_window import MainWindow
from systems.scene import load_scene

switches, seed = int(sys.argv[1]), int(sys.argv[2])
app = application()
scenes = sorted(Path("tests/user_systems").glob("*.toml"))
rng = random.Random(seed)
longest = [0.0, ""]

def timed(what, call):
    start = time.perf_counter()
    call()
    took = time.perf_counter() - start
    if took > longest[0]:
        longest[:] = [took, what]

def pump(seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        timed("processEvents", app.processEvents)
        time.sleep(0.005)

win = MainWindow()
win.show()
for i in range(switches):
    path = rng.choice(scenes)
    if rng.random() < 0.35:
        timed("close", win.close)
        win.deleteLater()
        pump(0.01)
        win = MainWindow()
        win.show()
    timed(f"open {path.stem}", lambda: win.open_scene(load_scene(path)))
    pump(rng.uniform(0.05, 2.5))
timed("close", win.close)
win.deleteLater()
pump(0.5)
time.sleep(3.0)
left = sorted(t.name for t in threading.enumerate() if t is not threading.main_thread())
print(json.dumps({"longest_s": longest[0], "longest": longest[1], "threads_left": left,
                  "import_lock_held": _imp.lock_held()}))
"""


def main(switches: int = SWITCHES, seed: int = SEED) -> bool:
    env = dict(os.environ)
    if not env.get("DISPLAY"):
        env.setdefault("QT_QPA_PLATFORM", "offscreen")
    out = subprocess.run(
        [sys.executable, "-c", CODE, str(switches), str(seed)], cwd=ROOT, env=env,
        capture_output=True, text=True, check=True, timeout=60 * switches,
    )  # fmt: skip
    r = json.loads(out.stdout.strip().splitlines()[-1])
    print(f"{switches} scene switches (seed {seed}), users' scenes, windows closed on the way")
    target = f"target < {STALL_TARGET:g} s"
    print(f"longest GUI-thread call: {r['longest_s']:.2f} s ({r['longest']}; {target})")
    print(f"threads left: {r['threads_left'] or 'none'}; import lock held: {r['import_lock_held']}")
    return r["longest_s"] < STALL_TARGET and not r["threads_left"] and not r["import_lock_held"]


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:3]]
    raise SystemExit(0 if main(*args) else 1)
