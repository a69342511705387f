"""Bad project files in the window: opening a fuzzed project either opens it (and fits it) or
shows one warning naming the file — never an exception in the window."""
from __future__ import annotations

import json

import pytest
from hypothesis import given

from prismstation.ops.project import create
from prismstation.io.project import project_to_dict
from tests.robustness import fuzzlib as fz

pytestmark = pytest.mark.gui


@pytest.fixture
def window(qtbot, tmp_path, monkeypatch):
    monkeypatch.setenv("PRISMSTATION_SETTINGS_DIR", str(tmp_path / "settings"))
    from prismstation.gui.main_window import MainWindow

    win = MainWindow(interactive=False, threaded_fit=False)
    win.files.interactive = False
    qtbot.addWidget(win)
    warnings = []
    win.files.warn = lambda title, text: warnings.append((title, text))
    return win, warnings


def test_fuzz_open_project_in_the_window(window, tmp_path, qtbot):
    win, warnings = window
    (tmp_path / "scene.json").write_text(json.dumps(fz.scene_doc()))
    (tmp_path / "p.csv").write_text(fz.points_csv_text())
    (tmp_path / "m.csv").write_text(fz.measurements_csv_text())
    proj = create(tmp_path / "valid.prismproj", tmp_path / "scene.json", tmp_path / "p.csv",
                  tmp_path / "m.csv", geoid="55.2")
    doc = project_to_dict(proj, tmp_path / "valid.prismproj")
    assert win.open_project(tmp_path / "valid.prismproj", recover=False)
    assert not warnings

    @fz.fuzz_settings(40)
    @given(data=fz.any_input(json.dumps(doc, indent=1), doc))
    def run(data):
        bad = tmp_path / "fuzz.prismproj"
        bad.write_bytes(data)
        win.files.stack.setClean()
        before = len(warnings)
        ok = win.open_project(bad, recover=False)
        qtbot.wait(1)
        new = warnings[before:]
        if ok:
            assert win.files.path is not None and win.files.path.name == bad.name
        else:
            assert len(new) == 1 and bad.name in new[0][1], new
            assert "\n" not in new[0][1].strip()

    run()
