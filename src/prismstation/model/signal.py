"""A minimal observer: plain Python, no Qt (the GUI connects Qt slots to it)."""
from __future__ import annotations


class Signal:
    def __init__(self):
        self._slots: list = []

    def connect(self, fn) -> None:
        if fn not in self._slots:
            self._slots.append(fn)

    def disconnect(self, fn) -> None:
        if fn in self._slots:
            self._slots.remove(fn)

    def emit(self, *args) -> None:
        for fn in list(self._slots):
            fn(*args)
