"""The last few results of pure fits, found again by the exact bytes of their inputs.

A click in the window refits every view, but moves the measurements of one: the bias fits of
the others and the parallax line get the same inputs as at the previous click. ``Recent``
returns the result computed then (an immutable object) instead of computing it again.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Callable

import numpy as np


def key_of(*parts) -> tuple:
    """A hashable key of ``parts``: arrays (or nested sequences of numbers) by dtype, shape and
    bytes, anything else (str, float, None) as it is."""
    out = []
    for p in parts:
        if isinstance(p, (str, int, float, type(None))):
            out.append(p)
        else:
            a = np.ascontiguousarray(p, dtype=float)
            out.append((a.shape, a.tobytes()))
    return tuple(out)


class Recent:
    """``get(key, compute)``: ``compute()`` the first time ``key`` is asked for, its result
    again while it is among the ``size`` keys asked for last (thread-safe)."""

    def __init__(self, size: int = 16):
        self.size = size
        self._items: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple, compute: Callable):
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        value = compute()
        with self._lock:
            self._items[key] = value
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        return value
