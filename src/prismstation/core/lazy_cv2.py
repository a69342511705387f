"""OpenCV, imported at its first use: ``from prismstation.core.lazy_cv2 import cv2``; and
:func:`lazy_module` for the same with another heavy module (matching's numba-compiled loops).

Start-up saving: importing OpenCV maps about 100 MB of libraries and starts its thread pool;
numba takes 0.3 s of CPU to import. A command that never matches, warps or filters
(``--version``, ``--help``, a refused input, most of the window's work) should not pay for
them, and under a tight memory limit (``ulimit -v``) the import crashes the process (a
segmentation fault, not an exception) before any handler can say what happened. Every module
that uses OpenCV takes ``cv2`` from here.
"""
from __future__ import annotations

import importlib


class _LazyModule:
    """Stands for the module ``name``: the first attribute read imports it."""

    def __init__(self, name: str):
        self._name = name
        self._module = None

    def __getattr__(self, attr):
        module = self.__dict__["_module"]
        if module is None:
            module = self.__dict__["_module"] = importlib.import_module(self.__dict__["_name"])
        value = getattr(module, attr)
        self.__dict__[attr] = value       # read directly from here on (matching's inner loops)
        return value


def lazy_module(name: str):
    """The module ``name``, imported when an attribute of it is first read."""
    return _LazyModule(name)


cv2 = _LazyModule("cv2")
