"""A new project's geoid: the scene's stated undulation, else the EGM96 grid found on PROJ's
paths (``auto``), the datum SRTM-like reference DEMs hold their heights in. With a constant 0 m
— the default before — a reference DEM's heights were read tens of metres off wherever the
geoid is far from 0, and nothing said so."""
from __future__ import annotations

import json

import pytest

from prismstation.cli import main
from prismstation.io.geoid import find_grid
from prismstation.io.project import load_project

from tests.cli.test_transfer_cli import n_only_project


@pytest.fixture()
def grid():
    g = find_grid()
    if g is None:
        pytest.skip("no EGM96 grid on PROJ's data paths (packaging/setup.sh installs proj-data)")
    return g


def test_a_scene_without_an_undulation_reads_its_srtm_through_egm96(foreign_data, grid, tmp_path, capsys):
    """The other simulator's scene (no undulation in its scene.json; points ellipsoidal; an
    SRTM-like reference above EGM96, which lies 56 m above the ellipsoid there): ``new`` without
    ``--geoid`` says which geoid it took, and ``transfer`` then finds all 41 check points in F
    and in B (with a constant 0 m it missed one in each, the search's heights 56 m low)."""
    d = foreign_data / "smooth_hills_10km"
    made, _, _ = n_only_project(d, tmp_path)          # for its N-only measurements
    proj = tmp_path / "plain.prismproj"
    assert main(["new", str(proj), "--scene", str(d / "scene.json"), "--points", str(d / "points.csv"),
                 "--measurements", str(tmp_path / "m.csv")]) == 0
    out = capsys.readouterr().out
    assert f"geoid grid {grid.name} (auto)" in out, out
    assert load_project(proj).geoid == {"kind": "auto", "value": 0.0}
    assert main(["fit", str(proj)]) == 0
    capsys.readouterr()
    assert main(["transfer", str(proj), "--dem", str(d / "srtm_like.tif")]) == 0
    assert "found: F 41 of 41, B 41 of 41" in capsys.readouterr().out


def test_a_stated_undulation_or_the_users_own_geoid_is_kept(foreign_data, tmp_path, capsys):
    d = foreign_data / "smooth_hills_10km"
    doc = json.loads((d / "scene.json").read_text())
    doc["views"] = {v: {**s, "image": str(d / s["image"])} for v, s in doc["views"].items()}
    stated = tmp_path / "scene.json"
    stated.write_text(json.dumps({**doc, "geoid_undulation_m": 51.5}))
    assert main(["new", str(tmp_path / "a.prismproj"), "--scene", str(stated)]) == 0
    assert load_project(tmp_path / "a.prismproj").geoid == {"kind": "constant", "value": 51.5}
    assert main(["new", str(tmp_path / "b.prismproj"), "--scene", str(d / "scene.json"), "--geoid", "0"]) == 0
    assert load_project(tmp_path / "b.prismproj").geoid == {"kind": "constant", "value": 0.0}
    assert "geoid constant 0 m" in capsys.readouterr().out


def test_no_grid_found_is_said(foreign_data, tmp_path, monkeypatch, capsys):
    """``auto`` where PROJ's paths hold no grid: 0 m, and ``new`` says why and what to do."""
    from prismstation.io import geoid as geoid_mod
    monkeypatch.setattr(geoid_mod, "find_grid", lambda *a, **k: None)
    d = foreign_data / "smooth_hills_10km"
    assert main(["new", str(tmp_path / "a.prismproj"), "--scene", str(d / "scene.json")]) == 0
    out = capsys.readouterr().out
    assert "geoid constant 0 m (auto: no EGM96/EGM2008 grid on PROJ's data paths" in out, out
    assert "--geoid" in out


@pytest.mark.parametrize("value", ["nan", "inf", "1e308", "-160"])
def test_an_undulation_no_geoid_has_is_refused_in_one_line(foreign_data, tmp_path, capsys, value):
    """``--geoid nan`` was stored as null (a project the next command could not use);
    ``inf``, ``1e308`` and ``-160`` as they were."""
    d = foreign_data / "smooth_hills_10km"
    assert main(["new", str(tmp_path / "a.prismproj"), "--scene", str(d / "scene.json"), "--geoid", value]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--geoid {value}: a constant undulation must lie within -150 to 150 m" in err[0]
    assert not (tmp_path / "a.prismproj").exists()


def test_a_project_file_whose_constant_geoid_has_no_value_is_named(foreign_data, tmp_path, capsys):
    d = foreign_data / "smooth_hills_10km"
    proj = tmp_path / "a.prismproj"
    assert main(["new", str(proj), "--scene", str(d / "scene.json"), "--geoid", "50"]) == 0
    doc = json.loads(proj.read_text())
    doc["geoid"] = {"kind": "constant", "value": None}
    proj.write_text(json.dumps(doc, indent=1))
    assert main(["fit", str(proj)]) == 2
    assert '"geoid": expected {"kind": "constant", "value": metres}' in capsys.readouterr().err
