"""``orient-dem`` and ``dsm`` on a project of images with RPCs, through the command line.

Synthetic triplet over a known terrain (:mod:`tests.ops.rpc_synth`: forward, nadir and backward
views, cubic RPCs, rendered by ray casting), written as GeoTIFFs with their RPCs in the tags,
whose RPCs are all off by one ground translation (a block error of 14 m east, −9 m north,
+4 m up, as a product without GCPs has). Tie points are the true terrain's points seen through
the true RPCs (0.05 px of noise). The reference DEM is the true terrain (1″, ellipsoidal), so
the orientation must find the translation within its σ and the DSM after it the terrain.
"""
from __future__ import annotations

import csv
import json
import shutil
from dataclasses import replace

import numpy as np
import pytest
import rasterio
from rasterio.rpc import RPC

from prismstation.cli import main
from prismstation.core.models.rpc_bias import metres_per_degree
from prismstation.core.adjustment.stats import nmad
from prismstation.io.project import load_project
from prismstation.io.rpc_scene import to_lonlat
from tests.ops.rpc_synth import World, analytic_terrain, make_rpc, render
from tests.ops.test_rpc_dsm import GSD, LAT0, LON0, SHIFT, SIZE, TANS, write_reference


def write_ties(path, paths, rpcs, lon, lat, h, rng, noise_px=0.05) -> None:
    """``path``: a tie-point CSV (id, view, x, y) of the ground points (lon, lat, h) projected
    by each image's true RPC, plus ``noise_px`` of normal noise on each coordinate."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "view", "x", "y"])
        for p, rpc in zip(paths, rpcs):
            x, y = rpc.project(lon, lat, h)
            for j in range(len(lon)):
                w.writerow([f"T{j:02d}", p.stem, x[j] + rng.normal(0, noise_px), y[j] + rng.normal(0, noise_px)])


def write_tagged(path, image, rpc) -> None:
    """The image as a GeoTIFF with ``rpc`` in its tags (GDAL's conventions, as :class:`Rpc`'s)."""
    tags = RPC(height_off=rpc.h_off, height_scale=rpc.h_scale, lat_off=rpc.lat_off, lat_scale=rpc.lat_scale,
               line_den_coeff=list(rpc.line_den), line_num_coeff=list(rpc.line_num), line_off=rpc.line_off,
               line_scale=rpc.line_scale, long_off=rpc.lon_off, long_scale=rpc.lon_scale,
               samp_den_coeff=list(rpc.samp_den), samp_num_coeff=list(rpc.samp_num), samp_off=rpc.samp_off,
               samp_scale=rpc.samp_scale)
    with rasterio.open(path, "w", driver="GTiff", width=image.shape[1], height=image.shape[0], count=1,
                       dtype="float32", rpcs=tags) as ds:
        ds.write(image, 1)


def make_block(d):
    """The synthetic block's images, tie points, reference DEM and project ``b.prismproj`` in
    folder ``d``: ``(d, world, true RPCs)``."""
    world = World(LON0, LAT0, analytic_terrain, extent_m=2400, texture_cell_m=2.0)
    ke, kn = metres_per_degree(LAT0)
    true, paths = [], []
    for k, t in enumerate(TANS):
        rpc = make_rpc(LON0, LAT0, gsd=GSD, size=SIZE, tan_along=t, h_off=400.0, h_scale=500.0, seed=k + 1)
        moved = replace(rpc, lon_off=rpc.lon_off - SHIFT[0] / ke, lat_off=rpc.lat_off - SHIFT[1] / kn,
                        h_off=rpc.h_off - SHIFT[2])
        write_tagged(d / f"img{k}.tif", render(rpc, world, SIZE), moved)
        true.append(rpc)
        paths.append(d / f"img{k}.tif")
    rng = np.random.default_rng(3)
    e, n = np.meshgrid(np.linspace(-420, 420, 8), np.linspace(-420, 420, 8))
    lon, lat = LON0 + e.ravel() / ke, LAT0 + n.ravel() / kn
    h = world.height(lon, lat)
    write_ties(d / "ties.csv", paths, true, lon, lat, h, rng)
    write_reference(d / "ref.tif", world)
    assert main(["new", str(d / "b.prismproj"), "--images", *map(str, paths), "--no-ties", "--measurements",
                 str(d / "ties.csv")]) == 0
    return d, world, true


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    return make_block(tmp_path_factory.mktemp("rpc_block"))


def truth_diff(path, world):
    with rasterio.open(path) as ds:
        h = ds.read(1, masked=True).filled(np.nan)
        t, crs = ds.transform, ds.crs
    E, N = np.meshgrid(t.c + t.a * (np.arange(h.shape[1]) + 0.5), t.f + t.e * (np.arange(h.shape[0]) + 0.5))
    lon, lat = to_lonlat(crs.to_wkt())(E, N)
    return h - world.height(lon, lat)


def test_orient_then_dsm(block, capsys):
    d, world, true = block
    proj = str(d / "b.prismproj")
    # before: one view held fixed, the block where the shifted RPCs put it — its DSM 4 m low,
    # written, and the command says that a bias the data cannot determine decides its heights
    assert main(["dsm", proj, "-o", str(d / "before.tif"), "--posting", "8"]) == 3
    cap = capsys.readouterr()
    assert "pairs (0, 1)-(0, 2): NMAD" in cap.out and "images see matched" in cap.out
    err = [ln for ln in cap.err.splitlines() if "HEIGHTS NOT FIXED" in ln]
    assert len(err) == 1 and "img2: b0" in err[0] and "fit --dem" in err[0]
    before = truth_diff(d / "before.tif", world)
    assert np.isfinite(before).mean() > 0.5

    assert main(["orient-dem", proj, str(d / "ref.tif"), "--save", "--json", str(d / "o.json")]) == 0
    doc = json.loads((d / "o.json").read_text())
    c = doc["coregistration"]
    s = np.array([c["shift_m"]["dx"], c["shift_m"]["dy"], c["dz"]])
    sig = np.array([c["sigma_m"]["dx"], c["sigma_m"]["dy"], c["sigma_dz"]])
    assert np.all(np.abs(s - SHIFT) < np.maximum(4 * sig, [1.5, 1.5, 0.75])), (s, sig)
    p = load_project(proj)
    assert p.settings.orientation == "dem" and p.dem_control["sensor"] == "rpc"
    assert set(p.dem_control["biases"]) == {"img0", "img1", "img2"}

    # the fit now starts from the reference's biases and holds no view fixed: the true
    # ground's points land where the true RPCs see them
    assert main(["fit", proj, "--json", str(d / "fit.json")]) == 0
    rep = json.loads((d / "fit.json").read_text())
    assert "no view held fixed" in " ".join(rep["messages"])
    # the reference entered through the orientation: a fit that also names it holds no tie
    # point to it (the DEM counted once, its σ not shrunk by a second look)
    assert main(["fit", proj, "--dem", str(d / "ref.tif"), "--json", str(d / "fit2.json")]) == 0
    rep2 = json.loads((d / "fit2.json").read_text())
    assert load_project(proj).orientation["reference_heights"] == 0
    assert "carries it already" in " ".join(rep2["messages"]), rep2["messages"]
    from prismstation.ops.fit import solve_project
    sol = solve_project(p)
    ke, kn = metres_per_degree(LAT0)
    e, n = np.meshgrid(np.linspace(-500, 500, 5), np.linspace(-500, 500, 5))
    lon, lat = LON0 + e.ravel() / ke, LAT0 + n.ravel() / kn
    hh = world.height(lon, lat)
    for v, rpc in zip(["img0", "img1", "img2"], true):
        x, y = rpc.project(lon, lat, hh)
        px, py = sol.model.models[v].project(lon, lat, hh)
        sigma = np.hypot(*doc["biases"][v]["sigma"][:2])
        assert np.hypot(px - x, py - y).max() < 3 * sigma + 0.15, (v, sigma)

    # the DSM after: on the terrain
    assert main(["dsm", proj, "-o", str(d / "after.tif"), "--posting", "8", "--reference", str(d / "ref.tif")]) == 0
    after = truth_diff(d / "after.tif", world)
    assert abs(np.nanmedian(after)) < 0.75 and nmad(after[np.isfinite(after)]) < 3.0
    assert abs(np.nanmedian(before) - np.nanmedian(after)) > 2.0


def test_refusals_and_low_fill(block, tmp_path, capsys):
    d, world, _ = block
    proj = str(d / "b.prismproj")
    # a flat reference gives the co-registration no horizontal hold: refused, nothing stored
    with rasterio.open(d / "ref.tif") as src:
        prof, z = src.profile, src.read(1)
    with rasterio.open(tmp_path / "flat.tif", "w", **prof) as dst:
        dst.write(np.full_like(z, float(np.mean(z))), 1)
    capsys.readouterr()
    assert main(["orient-dem", str(d / "b.prismproj"), str(tmp_path / "flat.tif"), "--json",
                 str(tmp_path / "f.json")]) == 3
    assert "REFUSED" in capsys.readouterr().err
    assert "NaN" not in (tmp_path / "f.json").read_text()
    # a window past the first image's edge (300 px): refused, one line
    capsys.readouterr()
    assert main(["dsm", proj, "-o", str(tmp_path / "x.tif"), "--window", "250", "0", "100", "100"]) == 2
    assert "not inside the first image" in capsys.readouterr().err and not (tmp_path / "x.tif").exists()
    assert main(["dsm", proj, "-o", str(tmp_path / "low.tif"), "--posting", "16", "--min-fill", "100.1"]) == 3
    assert (tmp_path / "low.tif").exists()


def test_dsm_window_and_fill(block, tmp_path, capsys):
    """``--window`` (pixels of the first image) crops the DSM of images with RPCs and ``--fill``
    fills its voids (mask 2), through the same export as the window's."""
    d, world, _ = block
    proj = str(d / "b.prismproj")
    assert main(["dsm", proj, "-o", str(tmp_path / "all.tif"), "--posting", "4"]) in (0, 3)
    capsys.readouterr()
    assert main(["dsm", proj, "-o", str(tmp_path / "part.tif"), "--posting", "2", "--window", "50", "50", "150", "150",
                 "--fill"]) in (0, 3)
    assert "filled" in capsys.readouterr().out
    with rasterio.open(tmp_path / "all.tif") as a, rasterio.open(tmp_path / "part.tif") as b:
        assert b.width < 1.4 * a.width and b.height < 1.4 * a.height   # 2 m cells over half the image
        m, h = b.read(2), b.read(1)
    seen = np.isfinite(m)
    assert np.isfinite(h[seen]).all() and (m[seen] == 2).any() and set(np.unique(m[seen])) <= {1.0, 2.0}


def test_a_height_datum_the_orientation_cannot_check_is_said(block, tmp_path, capsys):
    """The block's reference without its statement of ellipsoidal heights, read through a
    project geoid of a constant 0 m where EGM96 lies some 50 m above the ellipsoid: the
    orientation cannot tell which datum is right, and says so in its result."""
    d, _, _ = block
    w = tmp_path / "copy"
    shutil.copytree(d, w)
    doc = json.loads((w / "b.prismproj").read_text())
    doc["geoid"] = {"kind": "constant", "value": 0.0}
    (w / "b.prismproj").write_text(json.dumps(doc))
    with rasterio.open(w / "ref.tif", "r+") as ds:
        ds.update_tags(HEIGHTS="")
    assert main(["orient-dem", str(w / "b.prismproj"), str(w / "ref.tif")]) == 0
    out = capsys.readouterr().out
    assert "not checked: the reference's height datum" in out and "m low, and this orientation's heights" in out
