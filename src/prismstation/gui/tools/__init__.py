"""Workstation tools beyond measuring (matching, GCP-free orientation, DSMs, rectification…).

Each module of this package (other than ones starting with ``_``) defines
``install(window)``, called once when the main window is built: it adds its actions to
``window.tools_menu`` (and docks through ``window._dock``) and connects to the window's
signals. Modules are discovered, so adding a tool is adding a module; the main window stays
wiring only.
"""
from __future__ import annotations

import importlib
import pkgutil


def install_tools(window) -> None:
    """Install every tool; their docks start hidden until the operator opens one from the
    Tools or View menu (all shown at once, they made the window taller than a laptop; a tab
    group of hidden docks leaves a stray tab bar on screen, so they are not tabified here)."""
    before = set(window.docks)
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}").install(window)
    for k in window.docks:
        if k not in before:
            window.docks[k].hide()
