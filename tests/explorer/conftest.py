"""Qt fixtures for the explorer's tests.

``_no_dangling_qt`` (autouse, in the manner of napari's conftest) records every
``QThread`` and ``QTimer`` started during a test and fails the test if one is still
running when it ends: closing a window must stop everything it started.

``_gui_thread_collection`` (autouse) gives every test what a window gives its process:
Python's cyclic garbage collected on the GUI thread only (``explorer.gui_gc``).
"""

from __future__ import annotations

import time
import traceback
import weakref
from collections.abc import Iterator
from pathlib import Path

import pytest
from PySide6.QtCore import QThread, QTimer
from PySide6.QtWidgets import QApplication

from explorer.gui_gc import GuiThreadCollector

EXPLORER_TESTS = Path(__file__).resolve().parent


class QtActivity:
    """Threads and timers started while installed, with where they were started."""

    def __init__(self):
        self.threads: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self.timers: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def install(self, monkeypatch) -> None:
        thread_start = QThread.start
        timer_start = QTimer.start
        activity = self

        def start_thread(self, *args, **kwargs):
            activity.threads[self] = _caller()
            return thread_start(self, *args, **kwargs)

        def start_timer(self, *args, **kwargs):
            activity.timers[self] = _caller()
            return timer_start(self, *args, **kwargs)

        monkeypatch.setattr(QThread, "start", start_thread)
        monkeypatch.setattr(QTimer, "start", start_timer)

    def dangling(self) -> list[str]:
        """Descriptions of the threads still running and timers still active."""
        found = []
        for thread, where in list(self.threads.items()):
            try:
                running = thread.isRunning()
            except RuntimeError:  # the C++ object is gone: it cannot be running
                continue
            if running:
                found.append(f"QThread {thread.objectName()!r} still running, started at\n{where}")
        for timer, where in list(self.timers.items()):
            try:
                active = timer.isActive()
            except RuntimeError:
                continue
            if active:
                found.append(f"QTimer still active, started at\n{where}")
        return found


def _caller() -> str:
    frames = [f for f in traceback.extract_stack()[:-2] if "site-packages" not in f.filename]
    return "".join(traceback.format_list(frames[-3:]))


class GuiThreadCollection:
    """Python's cyclic garbage collected on the GUI thread only, from the first test that
    uses Qt until the next test outside ``tests/explorer`` (``hand_back``).

    A window does this for its lifetime (``explorer.gui_gc``); a test without one (a
    ``PhaseView`` alone), and every test after a window closed, had the interpreter's
    own collection, which runs in whichever thread allocates past a threshold. A section
    fill's thread writing its batch IR (about 10^5 objects) so freed the Qt objects that
    an earlier view or window had left in reference cycles, and PySide deadlocked: the
    fill thread in ``QObject::~QObject`` holding Qt's connection lock and waiting for the
    GIL, the GUI thread holding the GIL in ``runDeletionInMainThread`` and waiting for
    that lock (gdb, tests/explorer/test_section_fill.py after the window tests; another
    run crashed in a collection on the GUI thread while a fill thread wrote). Between
    tests the garbage is collected as the window's timer would (``collect_due``); the
    full collection (0.15-0.25 s of CPU) is paid once, when the explorer's tests hand
    the collection back, not after every test.
    """

    def __init__(self):
        self.collector: GuiThreadCollector | None = None

    def hold(self, app) -> None:
        """Collection on the GUI thread (``app``'s) from now on."""
        if self.collector is None:
            self.collector = GuiThreadCollector(app)
            self.collector.start()

    def collect_due(self) -> None:
        """Collect the generations past their thresholds, here (the GUI thread)."""
        if self.collector is not None:
            self.collector.collect_due()

    def hand_back(self) -> None:
        """Collect everything here (the GUI thread), then the interpreter's own collection
        again, both by the collector's ``stop`` (unless a window still holds it)."""
        if self.collector is not None:
            self.collector.stop()
            self.collector.setParent(None)
            self.collector = None


_COLLECTION = GuiThreadCollection()


@pytest.fixture(autouse=True)
def _gui_thread_collection(request) -> Iterator[GuiThreadCollection]:
    """Collection on the GUI thread for every test that uses Qt (``qtbot``, ``qapp``) or
    runs after one: its threads never free Qt objects (``GuiThreadCollection``)."""
    app = QApplication.instance()
    if app is None and {"qtbot", "qapp"} & set(request.fixturenames):
        app = request.getfixturevalue("qapp")
    if app is not None:
        _COLLECTION.hold(app)
    yield _COLLECTION
    _COLLECTION.collect_due()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item, nextitem):
    result = yield  # the test's fixtures are torn down: its windows closed and deleted
    if nextitem is None or not Path(nextitem.path).resolve().is_relative_to(EXPLORER_TESTS):
        _COLLECTION.hand_back()
    return result


@pytest.fixture(autouse=True)
def _no_dangling_qt(monkeypatch, request, _gui_thread_collection):
    activity = QtActivity()
    activity.install(monkeypatch)
    yield activity
    # threads that were asked to stop may need a moment to get there
    deadline = time.monotonic() + 2.0
    while activity.dangling() and time.monotonic() < deadline:
        from PySide6.QtWidgets import QApplication

        app = QApplication.instance()
        if app is not None:
            app.processEvents()
        time.sleep(0.02)
    left = activity.dangling()
    if left and "allow_dangling_qt" not in request.keywords:
        pytest.fail("the test left Qt activity behind:\n" + "\n".join(left), pytrace=False)


@pytest.fixture(autouse=True)
def _own_preferences(monkeypatch, tmp_path_factory):
    """Each test's window starts with no recent files: preferences in a folder of its own."""
    monkeypatch.setenv("PHASE_EXPLORER_CONFIG", str(tmp_path_factory.mktemp("config")))


@pytest.fixture
def qt_activity(_no_dangling_qt) -> QtActivity:
    """The recorder of the current test's threads and timers."""
    return _no_dangling_qt


@pytest.fixture
def window(qtbot):
    """The main window on the simple pendulum, shown; shut down after the test."""
    from explorer.app import create_window

    win = create_window("simple_pendulum")
    win.show()
    qtbot.waitUntil(lambda: win.compiled is not None, timeout=60000)
    yield win
    win.close()
    win.deleteLater()
    qtbot.wait(10)


@pytest.fixture
def blank_window(qtbot):
    """A main window with no scene opened yet (as ``open --session`` starts one)."""
    from explorer.app import application
    from explorer.main_window import MainWindow

    application()
    win = MainWindow()
    win.show()
    yield win
    win.close()
    win.deleteLater()
    qtbot.wait(10)


def wait_for_points(qtbot, win, count: int = 20, timeout: int = 60000, key: int = 0) -> None:
    """Wait until trajectory ``key`` of the window has ``count`` points."""

    def enough() -> bool:
        trajectory = win.store.trajectories.get(key)
        return trajectory is not None and len(trajectory.t) >= count

    qtbot.waitUntil(enough, timeout=timeout)


def assert_data_in_every_panel(window) -> None:
    """The main orbit runs (or ended well) with finite states, and the phase, conserved
    and configuration panels (mechanism and path) have its data."""
    import numpy as np

    main = window.store.main
    assert main.status in ("running", "ok"), main.message
    assert np.isfinite(main.y.data).all()
    window.store.mark_dirty()
    window._on_redraw_timer_timeout()
    assert window.phase_view._curves[0].point_count() >= 8
    conserved = window.conserved_view
    assert conserved._energy_curves[0].point_count() >= 8
    for i in conserved.conserved_momenta:
        assert conserved._momentum_curves[i].point_count() >= 8
    configuration = window.configuration_view
    if window.compiled.mechanics.scene.drawing is not None:
        x, y = configuration._bobs.getData()
        fixed_x, _ = configuration._fixed.getData()
        assert len(x) >= 1 and np.isfinite(x).all() and np.isfinite(y).all()
        assert len(x) + len(fixed_x) == len(window.compiled.point_names)
    if window.compiled.n >= 2:
        assert configuration._path.point_count() >= 8
    assert window.editor.title_edit.text() == window.compiled.mechanics.scene.title
