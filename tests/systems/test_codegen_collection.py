"""``codegen._collection_paused`` switches the cyclic collector off and back on in the main
thread only, where the window's GUI-thread collector (``explorer.gui_gc``) switches it."""

import gc
import threading

from systems import codegen


def test_a_pause_in_another_thread_leaves_the_switch_alone():
    entered, go_on = threading.Event(), threading.Event()

    def pausing() -> None:
        with codegen._collection_paused():
            entered.set()
            go_on.wait(60)

    was = gc.isenabled()
    gc.enable()
    worker = threading.Thread(target=pausing)
    try:
        worker.start()
        assert entered.wait(60)
        gc.disable()  # meanwhile a window's collector takes collection to the GUI thread
        go_on.set()
        worker.join()
        assert not gc.isenabled()  # a worker's pause that ended did not switch it back on
    finally:
        go_on.set()
        worker.join()
        (gc.enable if was else gc.disable)()


def test_a_pause_in_the_main_thread_restores_the_switch():
    was = gc.isenabled()
    try:
        for enabled in (True, False):
            (gc.enable if enabled else gc.disable)()
            with codegen._collection_paused():
                assert not gc.isenabled()
            assert gc.isenabled() is enabled
    finally:
        (gc.enable if was else gc.disable)()
