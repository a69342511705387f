import os
from pathlib import Path

import pytest

# Qt without a screen (PLATFORM.md): a plain `pytest` must be safe on a headless machine.
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data" / "real"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data/real`` beside the project; tests that need it skip where it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data/real is not beside this checkout")
    return SHARED_DATA


@pytest.fixture(autouse=True)
def temp_settings(tmp_path, monkeypatch):
    """Every test gets its own settings directory: the window's settings module honours
    ``PRISMSTATION_SETTINGS_DIR`` whenever it changes, so the user's own are never touched."""
    d = tmp_path / "settings"
    d.mkdir()
    monkeypatch.setenv("PRISMSTATION_SETTINGS_DIR", str(d))
    return d
