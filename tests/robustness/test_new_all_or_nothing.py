"""``new`` changes nothing when it fails: every input is read and checked before anything is
written, and the scene and the project are written as one change."""
from __future__ import annotations

import errno
import os

import pytest

from prismstation.cli import main
from prismstation.io.project import load_project
from tests.robustness import faults as ft
from tests.robustness.hostile import rpc_images


@pytest.fixture()
def block(tmp_path):
    """A folder with three RPC images and a valid project over them made by ``new``."""
    images = rpc_images(tmp_path / "imgs")
    project = tmp_path / "p.prismproj"
    assert main(["new", str(project), "--images", *map(str, images), "--no-ties"]) == 0
    return tmp_path, images, project


def _state(folder):
    return {f: ft.digest(folder / f) for f in ft.listing(folder)}


def test_force_with_a_bad_points_file_changes_nothing(block):
    d, images, project = block
    bad = d / "bad.csv"
    bad.write_text("id,E,N,H\nA,1,2\n")
    before = _state(d)
    # a different set of images: the scene would change too
    result = ft.run_cli(["new", project, "--images", *images[:2], "--no-ties", "--points", bad, "--force"])
    ft.assert_clean_failure(result, "new", "bad.csv")
    assert _state(d) == before
    load_project(project)


def test_a_bad_points_file_leaves_no_orphan_scene(tmp_path):
    images = rpc_images(tmp_path / "imgs")
    bad = tmp_path / "bad.csv"
    bad.write_text("id,E,N,H\nA,x,2,3\n")
    before = _state(tmp_path)
    result = ft.run_cli(["new", tmp_path / "q.prismproj", "--images", *images, "--no-ties", "--points", bad])
    ft.assert_clean_failure(result, "new", "bad.csv")
    assert _state(tmp_path) == before


def test_an_existing_project_without_force_is_refused_before_anything_is_written(block):
    d, images, project = block
    before = _state(d)
    result = ft.run_cli(["new", project, "--images", *images[:2], "--no-ties"])
    ft.assert_clean_failure(result, "new", "already exists")
    assert _state(d) == before


@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_a_failing_replace_at_any_step_puts_every_file_back(block, monkeypatch, k):
    """Scene and project both change; each rename in turn fails: both files as they were, no
    file left behind."""
    d, images, project = block
    before = {f: h for f, h in _state(d).items() if not f.endswith(".bak")}
    real, calls = os.replace, []

    def failing(*a, **kw):
        calls.append(a)
        if len(calls) == k:
            raise OSError(errno.EIO, "Input/output error")
        return real(*a, **kw)
    monkeypatch.setattr(os, "replace", failing)
    result = ft.run_cli(["new", project, "--images", *images[:2], "--no-ties", "--geoid", "12", "--force"])
    monkeypatch.setattr(os, "replace", real)
    ft.assert_clean_failure(result, "new", ("p.scene.json", "p.prismproj"))
    after = {f: h for f, h in _state(d).items() if not f.endswith(".bak")}
    assert after == before
    assert load_project(project).scene.views.keys() == {"img_01", "img_02", "img_03"}
