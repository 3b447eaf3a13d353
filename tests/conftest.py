"""Test-wide setup. Qt must be told to render offscreen before anything imports it, and
every cache the program writes, and the window's preferences, go to a temporary folder,
never the user's.

Under pytest-xdist (``make test`` runs three workers) each worker gets a folder of its
own inside that one, named after the worker (``gw0``, ``gw1``...): its own copy of the
drivers' cache, its own preferences. Derivations, remembered values and scenes' machine
code are shared (``SHARED_FOLDERS``).

``PHASE_EXPLORER_THOROUGH=1`` runs the slow property tests with their full example counts
(``examples``); by default they run fewer, still dozens.
"""

import contextlib
import os
import shutil
import signal
import tempfile
import threading

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

# A suite started in the background of a shell (``make test &``, nohup) inherits SIGINT
# ignored, and so would every command a test starts: the tests of Ctrl+C need it heard.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

THOROUGH = os.environ.get("PHASE_EXPLORER_THOROUGH", "") == "1"


def examples(default: int, thorough: int) -> int:
    """A property test's example count: ``thorough`` with PHASE_EXPLORER_THOROUGH=1."""
    return thorough if THOROUGH else default


_OWN_CACHE = None
if not os.environ.get("PHASE_EXPLORER_CACHE"):
    _OWN_CACHE = tempfile.mkdtemp(prefix="phase-explorer-tests-")
    os.environ["PHASE_EXPLORER_CACHE"] = _OWN_CACHE
# the window's preferences (recent files) likewise
if not os.environ.get("PHASE_EXPLORER_CONFIG"):
    _OWN_CACHE = _OWN_CACHE or tempfile.mkdtemp(prefix="phase-explorer-tests-")
    os.environ["PHASE_EXPLORER_CONFIG"] = os.path.join(_OWN_CACHE, "config")
# Python's bytecode, in the session's cache: with PYTHONDONTWRITEBYTECODE set (as on this
# project's machines) every worker and each of the hundreds of commands the tests start
# compiled the project's 150 modules from source again, 0.2-0.6 s a process. With a
# prefix Python reads bytecode only there, so the bytecode the installation keeps beside
# the libraries (sympy's, numpy's, Qt's, the standard library's) is linked in: without it
# each session compiled some 3 000 modules from source again (about 50 s of CPU in a
# profiled suite run; a first import of the libraries took 6.6 s instead of 2.3).
_LINKING: threading.Thread | None = None
_PROJECT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _link_installed_bytecode(prefix: str) -> None:
    """Link every ``__pycache__/*.pyc`` of the interpreter's paths (the libraries', not
    this project's own folder, and leaving test folders out) to where ``prefix`` has
    Python look for it."""
    import sys

    suffix = f".{sys.implementation.cache_tag}.pyc"

    def visit(folder: str) -> None:
        try:
            entries = list(os.scandir(folder))
        except OSError:
            return
        for entry in entries:
            if not entry.is_dir(follow_symlinks=False):
                continue
            if entry.name == "__pycache__":
                target = os.path.join(prefix, folder.lstrip(os.sep))
                os.makedirs(target, exist_ok=True)
                for compiled in os.scandir(entry.path):
                    if compiled.name.endswith(suffix):
                        with contextlib.suppress(OSError):
                            os.symlink(compiled.path, os.path.join(target, compiled.name))
            elif entry.name not in ("tests", "test") and not entry.name.endswith("-info"):
                visit(entry.path)

    for folder in dict.fromkeys(os.path.abspath(p) for p in sys.path if p):
        if os.path.isdir(folder) and folder != _PROJECT:  # a virtualenv inside it is visited
            visit(folder)


if "PYTHONPYCACHEPREFIX" not in os.environ:
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    os.environ["PYTHONPYCACHEPREFIX"] = os.path.join(os.environ["PHASE_EXPLORER_CACHE"], "bytecode")
    # beside the drivers' warm-up (pytest_configure), before any worker starts
    _LINKING = threading.Thread(
        target=_link_installed_bytecode, args=(os.environ["PYTHONPYCACHEPREFIX"],), daemon=True
    )
    _LINKING.start()
# An xdist worker inherits the folders the controller set (or the caller's): it takes a
# subfolder of its own; the controller removes the whole folder at the end.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
SHARED_FOLDERS = ("derivations", "values", "machine-code")
"""The cache folders xdist workers share (the controller's); the rest is each worker's."""
_SHARED_CACHE = os.environ["PHASE_EXPLORER_CACHE"]
if _WORKER:
    for _name in ("PHASE_EXPLORER_CACHE", "PHASE_EXPLORER_CONFIG"):
        os.environ[_name] = os.path.join(os.environ[_name], _WORKER)
    # the stepping loops the controller compiled (pytest_configure): a copy of its
    # kernel folder, modification times kept (numba checks them against its index)
    _kernels = os.path.join(_SHARED_CACHE, "kernels")
    if os.path.isdir(_kernels):
        shutil.copytree(
            _kernels,
            os.path.join(os.environ["PHASE_EXPLORER_CACHE"], "kernels"),
            dirs_exist_ok=True,
        )
    # Derivations, remembered values and scenes' machine code are shared: every file is
    # written whole under another name, then renamed (``systems.files``), so workers read
    # a complete file or none. Kept apart, each worker derived and compiled the catalogue
    # again (a third of the files were duplicates). Tests of damaged or missing entries
    # use caches of their own.
    os.makedirs(os.environ["PHASE_EXPLORER_CACHE"], exist_ok=True)
    for _name in SHARED_FOLDERS:
        _folder = os.path.join(_SHARED_CACHE, _name)
        os.makedirs(_folder, exist_ok=True)
        with contextlib.suppress(FileExistsError):
            os.symlink(_folder, os.path.join(os.environ["PHASE_EXPLORER_CACHE"], _name))


def pytest_configure(config):
    """Compile the integrators' stepping loops once for the whole session, as
    ``python main.py warm`` does after an installation: in the controller (or the only
    process), into the cache the workers copy."""
    if _WORKER:
        return
    from systems.integrators.warmup import drivers_warmed, warm_drivers

    _seed_drivers_from_installation()
    if not drivers_warmed():  # seeded from a complete warm-up: every loop is on disk
        warm_drivers()
    if _LINKING is not None:
        _LINKING.join()


def _seed_drivers_from_installation() -> None:
    """Copy the drivers ``python main.py warm`` left in the user's cache, if they are those
    of this source, into the session's cache: only read there, never written, and it
    saves a minute of compiling per session (``make test-quick`` warms first), and with
    the stamp of a complete warm-up the session loads nothing (``drivers_warmed``). A copy
    that does not verify is rebuilt like any damaged cache entry."""
    from pathlib import Path

    from systems.integrators.warmup import copy_drivers

    installed = Path.home() / ".cache" / "phase-explorer"
    if Path(_SHARED_CACHE).resolve() == installed.resolve():
        return  # the caller pointed the tests at the user's cache itself
    copy_drivers(installed, Path(_SHARED_CACHE))


SLOW_FIRST = (
    "tests/explorer/test_sessions.py",
    "tests/explorer/test_catalogue_window.py",
    "tests/explorer/test_user_scenes.py",
    "tests/explorer/test_window_model.py",
    "tests/systems/test_default_accuracy.py",
    "tests/explorer/test_window_faults.py",
    "tests/systems/test_simulation.py",
    "tests/systems/integrators/test_method_matrix.py",
    "tests/explorer/test_views_fit.py",
)
"""The files that take longest (a minute or more each), run first: ``make test``'s workers
take whole files (``--dist loadfile``) in collection order, and one of these collected
last kept one worker busy for minutes after the other had finished. (xdist 3.6+ then
sorts the files by their number of tests, so this order counts only among files of equal
size, unless ``--no-loadscope-reorder`` is given; with it, a work-precision test that
compiles numba in a thread from a cold cache hung CI for 10 minutes: see the session 11
note before turning it on.)"""


SOAK = frozenset(SLOW_FIRST) | {
    "tests/explorer/test_scene_switches.py",
    "tests/systems/integrators/test_brouwer.py",
    "tests/systems/test_expressions_fuzz.py",
    "tests/systems/test_large_systems.py",
    # robustness corpora that everyday work rarely touches, and the costliest (39% of the
    # quick run's test time): damaged caches recompile drivers, replays run sessions
    # whole, the hostile corpus starts hundreds of commands, screens and a real X server
    "tests/systems/test_cache_integrity.py",
    "tests/explorer/test_session_replay_truth.py",
    "tests/explorer/test_hostile_cli.py",
    "tests/explorer/test_window_fits_screen.py",
    "tests/explorer/test_xvfb.py",
    # property corpora over the catalogue, the users' scenes and generated ones
    "tests/systems/test_statements_agree.py",
    "tests/explorer/test_derive_any_scene.py",
}
"""Model-based, soak, robustness and property files marked ``soak``: ``make test-quick``
leaves them (and ``slow``) out for everyday work; ``make test``, what CI runs, takes
everything."""


def pytest_collection_modifyitems(session, config, items):
    import pytest

    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    for item in items:
        if item.nodeid.split("::", 1)[0] in SOAK:
            item.add_marker(pytest.mark.soak)

    def key(item) -> int:
        path = item.nodeid.split("::", 1)[0]
        return rank.get(path, len(SLOW_FIRST))

    items.sort(key=key)  # stable: every file keeps its own order


def pytest_sessionfinish(session, exitstatus):
    if _OWN_CACHE is not None:
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)
