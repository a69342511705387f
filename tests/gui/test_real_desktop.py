"""Start, maximize, quit and restart the workstation on a real X server with a window manager
(Xvfb + openbox), as a user does; offscreen never showed the crash these tests guard."""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

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
