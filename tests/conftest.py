"""Test-wide setup. Qt must be told to render offscreen before anything imports it, and
every cache the program writes, and the window's preferences, go to a temporary folder,
never the user's."""

import os
import shutil
import tempfile

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

_OWN_CACHE = None
if not os.environ.get("PHASE_EXPLORER_CACHE"):
    _OWN_CACHE = tempfile.mkdtemp(prefix="phase-explorer-tests-")
    os.environ["PHASE_EXPLORER_CACHE"] = _OWN_CACHE
# the window's preferences (recent files) likewise
if not os.environ.get("PHASE_EXPLORER_CONFIG"):
    _OWN_CACHE = _OWN_CACHE or tempfile.mkdtemp(prefix="phase-explorer-tests-")
    os.environ["PHASE_EXPLORER_CONFIG"] = os.path.join(_OWN_CACHE, "config")


def pytest_sessionfinish(session, exitstatus):
    if _OWN_CACHE is not None:
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)
