"""gui/relay: a worker's result reaches its receiver on the GUI thread, or the orphan callback
when the receiver has been deleted meanwhile."""
from __future__ import annotations

import threading

from PySide6.QtCore import QObject

from prismstation.gui import relay


class _Receiver(QObject):
    def __init__(self):
        super().__init__()
        self.got = []

    def take(self, *args):
        self.got.append((args, threading.current_thread() is threading.main_thread()))


def test_delivered_on_the_gui_thread_or_orphaned(qtbot):
    alive, doomed = _Receiver(), _Receiver()
    rid_alive, rid_doomed = relay.register(alive), relay.register(doomed)
    orphaned = []

    def worker():
        relay.post(rid_alive, "take", 1, "a")
        relay.post(rid_doomed, "take", 2, orphan=lambda: orphaned.append(
            threading.current_thread() is threading.main_thread()))
    doomed.deleteLater()
    qtbot.wait(10)                       # the doomed receiver is gone before the results come
    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert alive.got == []               # queued: nothing before the event loop runs
    qtbot.waitUntil(lambda: bool(alive.got and orphaned), timeout=3000)
    assert alive.got == [((1, "a"), True)]
    assert orphaned == [True]
