"""The command line reads a project with the images the window relocated
(``relocated_images``): the same images as the window, not the scene's missing ones."""
from __future__ import annotations

import json
import shutil

from prismstation.io.project import load_project
from tests.robustness import faults as ft


def _relocate(project_path, where: dict) -> None:
    """Record relocated images in the project file, as the window saves them."""
    doc = json.loads(project_path.read_text())
    doc["relocated_images"] = where
    project_path.write_text(json.dumps(doc))


def test_commands_use_the_relocated_images(sim, tmp_path):
    project_path = sim / "p.prismproj"
    moved = tmp_path / "moved"
    moved.mkdir()
    for v in ("N", "F", "B"):
        shutil.move(sim / f"{v}.tif", moved / f"{v}.tif")
    _relocate(project_path, {v: str(moved / f"{v}.tif") for v in ("N", "F", "B")})

    again = load_project(project_path)
    assert {v: view.image for v, view in again.scene.views.items()} == \
        {v: str(moved / f"{v}.tif") for v in ("N", "F", "B")}
    rc, out, err = ft.run_cli(["dsm", project_path, "-o", tmp_path / "d.tif", "--window", "300", "300",
                               "200", "200", "--posting", "10", "--min-fill", "0"])
    assert rc == 0 and (tmp_path / "d.tif").is_file(), err


def test_a_relative_relocation_is_read_from_the_project_folder(sim):
    project_path = sim / "p.prismproj"
    (sim / "moved").mkdir()
    shutil.move(sim / "N.tif", sim / "moved" / "N.tif")
    _relocate(project_path, {"N": "moved/N.tif"})
    assert load_project(project_path).scene.views["N"].image == str(sim / "moved" / "N.tif")
