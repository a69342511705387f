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
    """Install every tool; their docks go into one tab group, hidden until the operator opens
    one from the Tools or View menu (stacked, they made the window taller than a laptop)."""
    before = set(window.docks)
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}").install(window)
    new = [window.docks[k] for k in window.docks if k not in before]
    for d in new[1:]:
        window.tabifyDockWidget(new[0], d)
    for d in new:
        d.hide()
