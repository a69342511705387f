"""Start, maximize, quit and restart the workstation on a real X server with a window manager
(Xvfb + openbox), as a user does; offscreen never showed the crash these tests guard."""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.gui.xdesktop import App, Desktop, missing_tools

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="an X server is Linux-only")

DATA = Path(__file__).parent / "data"


@pytest.fixture()
def desktop(request):
    if missing_tools():  # packaging/setup.sh --test installs them
        pytest.fail(f"missing for the real-desktop tests: {', '.join(missing_tools())}")
    d = Desktop(*getattr(request, "param", (1600, 1000)))
    yield d
    d.close()


def settings_file(settings_dir: Path) -> Path:
    return settings_dir / "prismstation" / "prismstation.ini"


def test_maximize_quit_and_restart(desktop, demo, tmp_path):
    settings = tmp_path / "s"
    app = App(desktop, demo.path, settings)
    try:
        app.maximize()
        rc, out = app.quit()
        assert rc == 0, out
        assert "geometry=" in settings_file(settings).read_text()
        for _ in range(2):  # the crash came at every start after a maximize
            app = App(desktop, demo.path, settings)
            assert app.alive_for(3), f"exit {app.proc.returncode}:\n{app.proc.stdout.read()}"
            assert app.maximized()  # the saved state is honoured, not dropped
            rc, out = app.quit()
            assert rc == 0, out
    finally:
        app.kill()


def test_the_settings_a_maximized_window_left_behind(desktop, demo, tmp_path):
    """The ``[window]`` section a user's maximized session saved (1600 × 1000 screen) — it
    crashed every start in QLayout::activate."""
    settings = tmp_path / "s"
    settings_file(settings).parent.mkdir(parents=True)
    shutil.copy(DATA / "settings_after_maximize.ini", settings_file(settings))
    app = App(desktop, demo.path, settings)
    try:
        assert app.alive_for(3), f"exit {app.proc.returncode}:\n{app.proc.stdout.read()}"
        rc, out = app.quit()
        assert rc == 0, out
    finally:
        app.kill()


@pytest.mark.parametrize("desktop", [(1280, 720)], indirect=True)
def test_a_geometry_from_a_larger_screen_is_fitted_to_this_one(desktop, demo, tmp_path):
    settings = tmp_path / "s"
    settings_file(settings).parent.mkdir(parents=True)
    shutil.copy(DATA / "settings_after_maximize.ini", settings_file(settings))
    app = App(desktop, demo.path, settings)
    try:
        assert app.alive_for(2)
        x, y, w, h = app.geometry()
        assert x >= 0 and y >= 0 and x + w <= 1280 and y + h <= 720, (x, y, w, h)
        assert app.quit()[0] == 0
    finally:
        app.kill()


@pytest.mark.parametrize("desktop", [(1280, 720), (1920, 1080), (3840, 2160)], indirect=True)
def test_a_first_start_fits_the_screen(desktop, demo, tmp_path):
    app = App(desktop, demo.path, tmp_path / "s")
    try:
        sw, sh = map(int, desktop.run("xdotool", "getdisplaygeometry").stdout.split())
        x, y, w, h = app.geometry()
        assert x >= 0 and y >= 0 and x + w <= sw and y + h <= sh, (x, y, w, h)
        assert w >= min(1600, sw - 100) and h >= min(1000, sh - 100)
        assert app.quit()[0] == 0
    finally:
        app.kill()


def crosshair_pixels(desktop, box) -> int:
    """Pixels of the linked cursor's green (drawn blended: green well above red and blue) in
    ``box`` ``(x, y, w, h)`` of the screen (the images are grey; the plots' green lies outside)."""
    x, y, w, h = box
    px = desktop.screenshot()[y:y + h, x:x + w].astype(int)
    return int((px[..., 1] - np.maximum(px[..., 0], px[..., 2]) > 80).sum())


def test_the_linked_cursor_goes_when_the_mouse_leaves_the_view(desktop, demo, tmp_path):
    """The mouse over N draws the linked crosshair in F and B; moved out of the view (onto the
    table) the crosshairs go — they stayed where the mouse left."""
    app = App(desktop, demo.path, tmp_path / "s")
    try:
        x, y, w, h = app.geometry()
        views = (x, y + int(0.13 * h), int(0.75 * w), int(0.42 * h))  # below the toolbar, above the table, left of the docks
        desktop.run("xdotool", "windowactivate", "--sync", app.wid)
        assert app.alive_for(2)  # (images loaded)
        for k in range(5):  # over the middle of N (the left third of the views)
            desktop.run("xdotool", "mousemove", str(x + w // 8 + 3 * k), str(y + h // 3 + 2 * k))
        shown = desktop.wait(lambda: crosshair_pixels(desktop, views) > 30, 10, "the crosshairs in F and B")
        assert shown
        desktop.run("xdotool", "mousemove", str(x + w // 8), str(y + h - 60))  # the table
        desktop.wait(lambda: crosshair_pixels(desktop, views) == 0, 10, "the crosshairs to go")
        rc, out = app.quit()
        assert rc == 0, out
    finally:
        app.kill()
