"""Results from worker threads to GUI objects that may be gone by the time they arrive.

A worker must not emit on a QObject that its window may already have deleted. So there is one
process-wide relay, made on the GUI thread and never deleted: a worker :func:`post`\\ s to it,
the call is delivered queued on the GUI thread to the receiver registered under that id, if it
still exists — else ``orphan()`` runs (to close a file the result holds, say).
"""
from __future__ import annotations

import itertools
import weakref

import shiboken6
from PySide6.QtCore import QObject, Signal


class _Relay(QObject):
    posted = Signal(int, str, tuple, object)  # receiver id, method name, arguments, orphan


_RELAY: _Relay | None = None
_RECEIVERS: "weakref.WeakValueDictionary[int, QObject]" = weakref.WeakValueDictionary()
_IDS = itertools.count(1)


def register(receiver: QObject) -> int:
    """Id under which workers reach ``receiver`` (call on the GUI thread)."""
    global _RELAY
    if _RELAY is None:
        _RELAY = _Relay()
        _RELAY.posted.connect(_deliver)
    rid = next(_IDS)
    _RECEIVERS[rid] = receiver
    return rid


def post(rid: int, method: str, *args, orphan=None) -> None:
    """Call ``receiver.method(*args)`` on the GUI thread (from any thread)."""
    _RELAY.posted.emit(rid, method, args, orphan)


def _deliver(rid: int, method: str, args: tuple, orphan) -> None:
    receiver = _RECEIVERS.get(rid)
    if receiver is not None and shiboken6.isValid(receiver):
        getattr(receiver, method)(*args)
    elif orphan is not None:
        orphan()
