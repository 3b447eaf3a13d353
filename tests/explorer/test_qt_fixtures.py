"""The fixture that catches threads and timers left running does catch them."""

from PySide6.QtCore import QThread, QTimer


def test_dangling_thread_and_timer_are_reported(qtbot, qt_activity):
    thread = QThread()
    thread.setObjectName("leaky")
    timer = QTimer()
    thread.start()
    timer.start(1000)
    left = qt_activity.dangling()
    assert any("leaky" in entry for entry in left)
    assert any("QTimer" in entry for entry in left)
    thread.quit()
    assert thread.wait(2000)
    timer.stop()
    assert qt_activity.dangling() == []
