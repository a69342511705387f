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
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}").install(window)
