"""Every number read is checked for the range that makes sense for it: a file that would give
a wrong result with exit 0 (residuals of 1e307, a GCP silently turned into a tie point, a
bias of −534 m from heights in feet) is refused in one line naming the file."""
from __future__ import annotations

import json

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from tests.robustness import faults as ft


def _edit(path, change) -> None:
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc, indent=1))


def _gcp(doc):
    return next(p for p in doc["points"] if p["kind"] == "GCP")


@pytest.mark.parametrize("change, said", [
    (lambda d: d["measurements"][0].update(x=1e308), "far outside the image"),
    (lambda d: d["measurements"].append(dict(d["measurements"][0])), "measured twice"),
    (lambda d: d["points"].append({"id": _gcp(d)["id"], "kind": "TIE"}), "a tie point of that id would replace it"),
    (lambda d: _gcp(d).update(E=1e308), "is not a map coordinate"),
    (lambda d: _gcp(d).update(H=1e5), "is not a height on Earth"),
    (lambda d: _gcp(d).update(E=_gcp(d)["E"] + 5e5), "far from every image"),
    (lambda d: d.update(dem_control={"patches": [{"x": "a"}]}), "dem_control"),
    (lambda d: d.update(dem_control={"biases": {"N": {}}}), "dem_control"),
], ids=["x 1e308", "measured twice", "GCP id reused by a tie point", "E 1e308", "H 1e5", "far away",
        "garbage dem_control", "an RPC record in a triplet"])
def test_a_project_file_with_an_impossible_number(sim, change, said):
    project = sim / "p.prismproj"
    _edit(project, change)
    line = ft.assert_clean_failure(ft.run_cli(["fit", project]), "fit", "p.prismproj")
    assert said in line, line


@pytest.mark.parametrize("change, said", [
    (lambda d: d["views"]["N"].update(pixel_size_m=1e308), "pixel_size_m"),
    (lambda d: d.update(satellite_altitude_m=1e308), "satellite_altitude_m"),
    (lambda d: d.update(geoid_undulation_m=5000), "geoid_undulation_m"),
    (lambda d: d.update(crs="EPSG:2227"), "US survey foot"),
], ids=["pixel size", "altitude", "undulation", "CRS in feet"])
def test_a_scene_with_an_impossible_number(sim, change, said):
    _edit(sim / "scene.json", change)
    line = ft.assert_clean_failure(ft.run_cli(["fit", sim / "p.prismproj"]), "fit", "scene.json")
    assert said in line, line


def test_tables_with_impossible_numbers(sim, tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("id,view,x,y\nA,N,1e308,5\n")
    line = ft.assert_clean_failure(ft.run_cli(["new", tmp_path / "n.prismproj", "--scene", sim / "scene.json",
                                               "--measurements", m]), "new", "m.csv")
    assert "line 2" in line and "not an image coordinate" in line
    g = tmp_path / "g.csv"
    g.write_text("id,E,N,H\nA,1e308,5,3\n")
    line = ft.assert_clean_failure(ft.run_cli(["new", tmp_path / "n.prismproj", "--scene", sim / "scene.json",
                                               "--points", g]), "new", "g.csv")
    assert "line 2" in line and "not a map coordinate" in line
    assert not (tmp_path / "n.prismproj").exists()


def test_bh_with_an_impossible_position():
    line = ft.assert_clean_failure(ft.run_cli(["bh", "--left", "0", "0", "1e308", "--right", "1", "0", "1"]),
                                   "bh", "--left")
    assert "finite" in line


def _dem(path, crs, value=100.0):
    with rasterio.open(path, "w", driver="GTiff", width=20, height=20, count=1, dtype="float32", crs=crs,
                       transform=from_origin(6_000_000, 2_000_000, 100, 100)) as ds:
        ds.write(np.full((1, 20, 20), value, np.float32))


def test_a_dem_in_feet(tmp_path):
    """A DEM whose CRS is in US survey feet and says nothing of its heights is refused (its
    heights are feet as often as metres); one whose CRS names feet for its heights is converted."""
    from prismstation.io.dem import read_dem
    _dem(tmp_path / "ft.tif", "EPSG:2227")
    _dem(tmp_path / "m.tif", "EPSG:2227")
    line = ft.assert_clean_failure(ft.run_cli(["validate-dsm", tmp_path / "ft.tif", tmp_path / "m.tif", "--reference-height", "orthometric", "--geoid-constant", "0", "--json", tmp_path / "v.json"]),
                                   "validate-dsm", "ft.tif")
    assert "US survey foot" in line
    _dem(tmp_path / "ftv.tif", "EPSG:2227+6360", 1000.0)
    assert read_dem(tmp_path / "ftv.tif").heights[0, 0] == pytest.approx(304.8006, abs=1e-3)
