"""Application set-up and :func:`run`: the workstation window, or a screenshot of it.

``run(project, screenshot=PNG)`` loads the project, fits, waits for the images to settle,
writes a PNG of the whole main window (``QWidget.grab``) and returns 0; it works with
``QT_QPA_PLATFORM=offscreen`` and never asks a question.
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

from prismstation.errors import InputError
from prismstation.gui import settings, workers
from prismstation.gui.main_window import MainWindow
from prismstation.io.atomic import OWNER_TAG, clean_stale
from prismstation.io.raster import gdal_env


def icon_path():
    """The application icon: ``resources/icons`` beside the source tree, or inside a
    PyInstaller bundle; None when neither is there (a wheel install without resources)."""
    roots = [Path(__file__).resolve().parents[3] / "resources"]
    if getattr(sys, "_MEIPASS", None):
        roots.insert(0, Path(sys._MEIPASS) / "resources")
    for r in roots:
        p = r / "icons" / "prismstation-256.png"
        if p.is_file():
            return p
    return None


def make_app():
    """The QApplication (created once), with names, settings location and pyqtgraph options."""
    import pyqtgraph as pg
    from PySide6.QtWidgets import QApplication

    app = QApplication.instance() or QApplication(sys.argv[:1])
    icon = icon_path()
    if icon is not None:
        from PySide6.QtGui import QIcon
        app.setWindowIcon(QIcon(str(icon)))
    settings.configure()
    # live views and plots repaint at every click: lines without antialiasing draw twice as
    # fast (markers are pre-rendered pixmaps either way); report figures turn it back on
    pg.setConfigOptions(imageAxisOrder="row-major", antialias=False)
    app.setStyle("Fusion")
    # a refit allocates thousands of short-lived objects: with the default threshold (700) the
    # collector ran ~4 times per click and a full collection (~50 ms) now and then mid-click
    import gc
    gc.set_threshold(20000, 10, 10)
    workers.collect_on_gui_thread()  # a worker thread must never free a Qt object
    return app


def wait_settled(window, timeout_ms: int = 15000) -> bool:
    """Process events until images are loaded, the fit published and every tile shown."""
    from PySide6.QtCore import QCoreApplication, QElapsedTimer, QThread

    t = QElapsedTimer()
    t.start()
    window.views.wait_loaded(timeout_ms)

    def settled():
        return (not window.views.loading() and not window.solver.busy()
                and all(v.tiles_complete() for v in window.views.views.values()))

    while not settled() and t.elapsed() < timeout_ms:
        QCoreApplication.processEvents()
        QThread.msleep(5)
    for _ in range(5):
        QCoreApplication.processEvents()
    return settled()


def take_screenshot(window, path, size=(1680, 1050)) -> None:
    """Fit the views, let everything settle and save a PNG of the whole window."""
    window.resize(*size)
    window.show()
    window.default_layout()
    wait_settled(window)
    window.views.fit_all()
    if window.solver.solution is None and window.project is not None:
        window.solver.refit_now()
    wait_settled(window)
    window.solver.refit_now()  # the status bar then shows a warm fit time, not the first one
    sol = window.solver.solution
    if sol is not None and window.current is None:
        gcp = next((r.id for r in sol.points if r.kind == "GCP" and r.measured), None)
        if gcp is not None:
            window.set_current(gcp, drive=False)
            ref = sol.reference_view
            xy = window.views.point_position(gcp, ref)
            if xy is not None and ref in window.views.views:  # the linked cursor on that GCP
                window.views.on_cursor(ref, *xy)
    wait_settled(window)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    if not window.grab().save(str(path)):
        raise InputError("could not write the screenshot", path)


def run(project_path=None, screenshot=None, reference_dem=None, demo_maker=None, open_demo=False) -> int:
    """Open the window (on ``project_path``, with ``reference_dem`` loaded when given) and run
    the event loop; with ``screenshot`` (a PNG path) write a picture of the loaded, fitted
    window instead and return 0. ``demo_maker``: ``demo_maker(progress=…)`` makes the demo
    project and returns its path (the start page's "Open the demo project"); ``open_demo``:
    the window, once shown, makes it (with a progress dialog) and opens it."""
    screenshot_path = screenshot
    if project_path is not None and not Path(project_path).exists():
        raise InputError("project not found", project_path)
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                    or os.environ.get("QT_QPA_PLATFORM"))
    if headless and screenshot_path is not None:
        os.environ["QT_QPA_PLATFORM"] = "offscreen"  # a picture needs no screen
    elif headless and sys.platform.startswith("linux"):
        print("prismstation: no display (DISPLAY is not set); run it in a desktop session, or "
              "write a picture with --screenshot PNG", file=sys.stderr)
        return 2
    settings_dir = None
    if screenshot_path is not None:
        if "PRISMSTATION_SETTINGS_DIR" not in os.environ:  # never the user's layout in a picture
            clean_stale(tempfile.gettempdir(), "prismstation-settings-", folders=True)  # a killed run's
            settings_dir = tempfile.mkdtemp(prefix=f"prismstation-settings-{OWNER_TAG}_")
            os.environ["PRISMSTATION_SETTINGS_DIR"] = settings_dir
    try:
        with gdal_env():                 # the window's GDAL settings, for as long as it runs
            return _run_window(project_path, screenshot_path, reference_dem, demo_maker, open_demo)
    finally:
        if settings_dir is not None:  # the picture's settings folder goes with it
            shutil.rmtree(settings_dir, ignore_errors=True)
            os.environ.pop("PRISMSTATION_SETTINGS_DIR", None)


def _run_window(project_path, screenshot_path, reference_dem, demo_maker, open_demo) -> int:
    app = make_app()

    interactive = screenshot_path is None
    win = MainWindow(interactive=interactive, demo_maker=demo_maker)
    win.files.interactive = interactive
    if project_path is not None:
        win.show()
        if not win.open_project(str(project_path), recover=None if interactive else False):
            if not interactive:
                return 2
        elif reference_dem is not None:
            win.load_reference_dem(reference_dem, wait=not interactive)
    elif open_demo:
        from PySide6.QtCore import QTimer
        QTimer.singleShot(0, win.open_demo)  # the window first, then the demo's progress
    elif interactive:
        win.files.recover_untitled()
    if screenshot_path is not None:
        take_screenshot(win, screenshot_path)
        win.files.stack.setClean()
        win.close()
        return 0
    win.show()
    return app.exec()
