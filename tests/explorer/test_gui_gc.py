import gc

from explorer.gui_gc import GuiThreadCollector


def test_collects_on_the_gui_thread_and_restores_automatic_gc(qtbot):
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


def test_window_installs_the_textbook_dock_once(window):
    from explorer.textbook import install

    assert "textbook" in window.docks
    assert install(window) is window.textbook
