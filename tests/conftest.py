import os
import sys
from pathlib import Path

import pytest

# Qt without a screen: a plain `pytest` must be safe on a headless machine.
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data" / "real"
FOREIGN_DATA = ROOT.parent / "shared" / "data" / "foreign"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data/real`` beside the project; tests that need it skip where it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data/real is not beside this checkout")
    return SHARED_DATA


@pytest.fixture(scope="session")
def foreign_data() -> Path:
    """``../shared/data/foreign``: scenes another simulator made; skipped where absent."""
    if not FOREIGN_DATA.is_dir():
        pytest.skip("../shared/data/foreign is not beside this checkout")
    return FOREIGN_DATA


@pytest.fixture(autouse=True)
def temp_settings(tmp_path, monkeypatch):
    """Every test gets its own settings directory: the window's settings module honours
    ``PRISMSTATION_SETTINGS_DIR`` whenever it changes, so the user's own are never touched."""
    d = tmp_path / "settings"
    d.mkdir()
    monkeypatch.setenv("PRISMSTATION_SETTINGS_DIR", str(d))
    return d


@pytest.fixture(scope="session", autouse=True)
def qt_application():
    """The process's QApplication, made before any test: a test that makes a QGuiApplication
    first (icons) would leave the widget tests of the same worker without one."""
    try:
        from PySide6.QtWidgets import QApplication
    except ImportError:
        yield None
        return
    yield QApplication.instance() or QApplication(sys.argv[:1])


@pytest.fixture(autouse=True)
def collect_garbage_between_tests():
    """The window collects garbage from a GUI-thread timer (gui/workers.py); between tests,
    when no event loop runs, collect here, on the main thread, when it is due."""
    yield
    workers = sys.modules.get("prismstation.gui.workers")
    if workers is not None:
        workers.collect_if_due()
