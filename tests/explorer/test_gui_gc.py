import gc
import threading

from explorer.gui_gc import GuiThreadCollector


def test_collects_on_the_gui_thread_and_restores_automatic_gc(qtbot, _gui_thread_collection):
    _gui_thread_collection.hand_back()  # the tests' own (conftest) steps aside
    assert gc.isenabled()
    collector = GuiThreadCollector(interval_ms=10)
    collector.start()
    try:
        assert not gc.isenabled()

        class Node:
            pass

        for _ in range(5000):  # cycles that only the cyclic collector can free
            a, b = Node(), Node()
            a.other, b.other = b, a
        qtbot.waitUntil(lambda: gc.get_count()[0] < collector.threshold[0], timeout=3000)
    finally:
        collector.stop()
    assert gc.isenabled()


def test_the_last_collector_frees_what_is_left_on_the_gui_thread_before_handing_back(
    qtbot, _gui_thread_collection
):
    """When the last window closes, the garbage left in cycles is freed on the GUI thread
    before the interpreter collects again in whichever thread allocates: a window's
    thread not yet ended at close (a section fill's) would otherwise free the window's
    Qt objects, and PySide deadlocks there."""
    _gui_thread_collection.hand_back()  # the tests' own (conftest) steps aside
    freed_in = []

    class Cycle:
        def __del__(self):
            freed_in.append(threading.get_ident())

    collector = GuiThreadCollector(interval_ms=60_000)  # its timer never fires here
    collector.start()
    cycle = Cycle()
    cycle.me = cycle
    del cycle
    collector.stop()
    assert gc.isenabled()
    assert freed_in == [threading.get_ident()]


def test_a_thread_of_a_qt_test_never_frees_garbage(qtbot):
    """As in a window's process: a thread allocating past the collector's thresholds (a
    section fill writing its batch IR) leaves the cyclic garbage, which in a test holds
    the Qt objects of earlier views, to the GUI thread (conftest's
    ``GuiThreadCollection``; freed in the thread, such objects deadlocked PySide)."""
    freed_in = []

    class Cycle:
        def __del__(self):
            freed_in.append(threading.get_ident())

    def allocate() -> None:
        cycle = Cycle()
        cycle.me = cycle
        del cycle
        kept = [[] for _ in range(100_000)]  # past the first threshold 140 times
        assert len(kept) == 100_000

    worker = threading.Thread(target=allocate)
    worker.start()
    worker.join()
    assert freed_in == []
    gc.collect()
    assert freed_in == [threading.get_ident()]


def test_window_installs_the_textbook_dock_once(window):
    from explorer.textbook import install

    assert "textbook" in window.docks
    assert install(window) is window.textbook
