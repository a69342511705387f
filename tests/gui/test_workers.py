"""gui/workers: a worker's result reaches its receiver on the GUI thread, or the orphan callback
when the receiver has been deleted meanwhile; a closed group has joined its threads."""
from __future__ import annotations

import threading
import time

import pytest
from PySide6.QtCore import QObject

from prismstation.gui import workers


class _Receiver(QObject):
    def __init__(self):
        super().__init__()
        self.got = []

    def take(self, *args):
        self.got.append((args, threading.current_thread() is threading.main_thread()))


def test_delivered_on_the_gui_thread_or_orphaned(qtbot):
    alive, doomed = _Receiver(), _Receiver()
    orphaned = []
    jobs = workers.Jobs("test")

    def worker(take_alive, take_doomed):
        workers.post(take_alive, 1, "a")
        workers.post(take_doomed, 2, orphan=lambda: orphaned.append(
            threading.current_thread() is threading.main_thread()))
    take_doomed = doomed.take
    doomed.deleteLater()
    qtbot.wait(10)                       # the doomed receiver is gone before the results come
    jobs.start(worker, alive.take, take_doomed)
    assert jobs.close(5)
    qtbot.wait(10)
    assert alive.got == [((1, "a"), True)]
    assert orphaned == [True]


def test_close_cancels_joins_and_refuses(qtbot):
    jobs = workers.Jobs("test")
    started = threading.Event()

    def loop():
        started.set()
        while not jobs.cancelled.wait(0.01):
            pass
    t = jobs.start(loop)
    assert started.wait(5) and t in workers.live() and jobs.busy()
    assert jobs.close(5)
    assert not t.is_alive() and t not in workers.live()
    with pytest.raises(RuntimeError):
        jobs.start(loop)


def test_a_receiver_error_does_not_stop_other_deliveries(qtbot, monkeypatch):
    seen, errors = [], []
    monkeypatch.setattr("sys.excepthook", lambda *exc: errors.append(exc[0]))

    def boom():
        raise ValueError("receiver bug")
    jobs = workers.Jobs("test")
    jobs.start(lambda: (workers.post(boom), workers.post(seen.append, 1)))
    jobs.close(5)
    deadline = time.monotonic() + 5
    while not seen and time.monotonic() < deadline:
        qtbot.wait(5)
    assert seen == [1] and errors == [ValueError]
