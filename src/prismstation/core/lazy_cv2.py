"""OpenCV, imported at its first use: ``from prismstation.core.lazy_cv2 import cv2``.

Start-up saving: importing OpenCV maps about 100 MB of libraries and starts its thread pool. A
command that never matches, warps or filters (``--version``, ``--help``, a refused input, most
of the window's work) should not pay for it, and under a tight memory limit (``ulimit -v``)
the import crashes the process (a segmentation fault, not an exception) before any handler
can say what happened. Every module that uses OpenCV takes ``cv2`` from here.
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
        return getattr(module, attr)


cv2 = _LazyModule("cv2")
