"""One RPC orientation kept in the project, through the command line: a pair whose right RPC's
line offset is off by tens of pixels, rendered on real relief (the SRTM tile around Mont
Ventoux; skipped where the shared data are absent), with that tile as the reference DEM.

``fit --dem REF`` stores its settings and result; ``dsm`` then fits with the stored reference
and its DSM sits on the reference; without a reference ``dsm`` says in one line that an
undetermined bias decides the heights and exits 3. The images are rendered on the tile's own
numbers (taken as ellipsoidal: the project's geoid is 0), so the reference is the truth and the
DSM − reference median measures the orientation alone.
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import rasterio

from prismstation.cli import main
from prismstation.core.models.rpc_bias import metres_per_degree
from prismstation.io.project import load_project, save_project
from prismstation.io.rpc_scene import to_lonlat
from tests.cli.test_rpc_workflows import write_tagged, write_ties
from tests.ops.rpc_synth import World, dem_terrain, make_rpc, render

LON0, LAT0 = 5.27, 44.17          # the southern slopes of Mont Ventoux, on tile N44E005
SIZE, GSD = 300, 1.0               # a 300 m crop: too small for orient-dem's surface matching
TANS = (0.15, -0.15)               # B/H 0.3
LINE_BIAS_PX = 40.0                # the right RPC's line offset error: 40 m along track


def make_pair(d, srtm):
    """The pair's images (the right one's RPC off by :data:`LINE_BIAS_PX` along the lines),
    49 tie points (the true RPCs' projections of the terrain, 0.05 px of noise) and the project
    ``p.prismproj`` (geoid 0) in folder ``d``: ``(d, world, srtm)``."""
    height = dem_terrain(srtm)
    world = World(LON0, LAT0, lambda e, n: 0.0, extent_m=1000, texture_cell_m=0.5)
    world.height = lambda lon, lat: height(lon, lat)
    true, paths = [], []
    for k, t in enumerate(TANS):
        rpc = make_rpc(LON0, LAT0, gsd=GSD, size=SIZE, tan_along=t, h_off=1200.0, h_scale=800.0, seed=k + 1)
        written = replace(rpc, line_off=rpc.line_off + (LINE_BIAS_PX if k == 1 else 0.0))
        write_tagged(d / f"img{k}.tif", render(rpc, world, SIZE), written)
        true.append(rpc)
        paths.append(d / f"img{k}.tif")
    ke, kn = metres_per_degree(LAT0)
    rng = np.random.default_rng(5)
    e, n = np.meshgrid(np.linspace(-110, 110, 7), np.linspace(-110, 110, 7))
    lon, lat = LON0 + e.ravel() / ke, LAT0 + n.ravel() / kn
    h = world.height(lon, lat)
    write_ties(d / "ties.csv", paths, true, lon, lat, h, rng)
    assert main(["new", str(d / "p.prismproj"), "--images", *map(str, paths), "--no-ties", "--geoid", "0",
                 "--measurements", str(d / "ties.csv")]) == 0
    return d, world, srtm


@pytest.fixture(scope="module")
def pair(tmp_path_factory, shared_data):
    return make_pair(tmp_path_factory.mktemp("rpc_orientation"), shared_data / "srtm" / "N44E005.hgt")


def dsm_minus_truth(path, world) -> np.ndarray:
    with rasterio.open(path) as ds:
        h = ds.read(1, masked=True).filled(np.nan)
        t, crs = ds.transform, ds.crs
    E, N = np.meshgrid(t.c + t.a * (np.arange(h.shape[1]) + 0.5), t.f + t.e * (np.arange(h.shape[0]) + 0.5))
    lon, lat = to_lonlat(crs.to_wkt())(E, N)
    d = h - world.height(lon, lat)
    return d[np.isfinite(d)]


def test_no_reference_refuses_to_vouch_for_the_heights(pair, tmp_path, capsys):
    d, world, _ = pair
    proj = str(d / "p.prismproj")
    capsys.readouterr()
    assert main(["dsm", proj, "-o", str(tmp_path / "free.tif"), "--posting", "4"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    line = [ln for ln in err if "HEIGHTS NOT FIXED" in ln]
    assert len(line) == 1 and "img1: b0" in line[0] and "fit --dem" in line[0], err
    # and it is true: the DSM is tens of metres off the terrain
    off = dsm_minus_truth(tmp_path / "free.tif", world)
    assert abs(np.median(off)) > 50.0


def test_fit_with_the_reference_is_stored_and_the_dsm_sits_on_it(pair, tmp_path, capsys):
    d, world, srtm = pair
    proj = str(d / "p.prismproj")
    # the crop is too small for the surface matching: orient-dem says so and names the way
    capsys.readouterr()
    assert main(["orient-dem", proj, str(srtm)]) == 3
    err = capsys.readouterr().err
    assert "fit --dem" in err, err

    assert main(["fit", proj, "--dem", str(srtm), "--dem-sigma", "6", "--json", str(tmp_path / "f.json")]) == 0
    out = capsys.readouterr().out
    assert "stored in" in out and "held to the reference DEM" in out
    p = load_project(proj)
    assert p.reference_dem == str(srtm.resolve()) and p.settings.reference_sigma_m == 6.0
    rec = p.orientation
    b = rec["views"]["img1"]
    assert rec["views"]["img0"]["fixed"] and rec["reference_heights"] == 49 and rec["gcps"] == 0
    assert b["names"] == ["a0", "b0"] and all(b["determined"])
    sb0 = float(np.sqrt(b["cov"][1][1]))
    # the written RPC puts the ground 40 px further down the lines: the bias takes it back
    assert abs(b["params"][1] + LINE_BIAS_PX) < max(3 * sb0, 0.5), (b["params"], sb0)
    # fit again without options: the stored settings, nothing to store
    assert main(["fit", proj]) == 0
    assert "stored in" not in capsys.readouterr().out
    assert load_project(proj).orientation == rec

    # dsm reads the stored orientation: no option repeats the reference for the fit
    assert main(["dsm", proj, "-o", str(tmp_path / "on.tif"), "--posting", "4"]) == 0
    cap = capsys.readouterr()
    assert "HEIGHTS NOT FIXED" not in cap.err
    off = dsm_minus_truth(tmp_path / "on.tif", world)
    assert off.size > 2000
    assert abs(np.median(off)) < 6.0, np.median(off)       # the reference's own σ
    assert main(["dsm", proj, "-o", str(tmp_path / "ref.tif"), "--posting", "4", "--reference", str(srtm)]) == 0
    assert abs(np.median(dsm_minus_truth(tmp_path / "ref.tif", world))) < 6.0

    # report reads the same
    assert main(["report", proj, "-o", str(tmp_path / "r.json")]) == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["settings"]["reference_sigma_m"] == 6.0


def test_a_bias_per_view_and_a_stale_result(pair, tmp_path, capsys):
    d, world, srtm = pair
    proj = str(d / "q.prismproj")                # beside the scene and images
    (d / "q.prismproj").write_bytes((d / "p.prismproj").read_bytes())
    assert main(["fit", proj, "--dem", str(srtm), "--bias", "img1=shift_drift"]) == 0
    p = load_project(proj)
    assert p.settings.view_bias == (("img1", "shift_drift"),) and p.settings.bias_model == "shift"
    assert p.orientation["views"]["img1"]["names"] == ["a0", "b0", "b2"]
    assert p.orientation["views"]["img0"]["fixed"]
    assert main(["fit", proj, "--bias", "img1=nothing"]) == 2
    # settings edited elsewhere: the stored result is not the one dsm fits, and it says so
    p.set_settings(replace(p.settings, reference_sigma_m=8.0))
    save_project(p, proj)
    capsys.readouterr()
    assert main(["dsm", proj, "-o", str(tmp_path / "s.tif"), "--posting", "8"]) == 0
    assert "changed since fit stored its orientation" in capsys.readouterr().err
    # every view one model again
    assert main(["fit", proj, "--bias", "shift"]) == 0
    assert load_project(proj).settings.view_bias == ()
