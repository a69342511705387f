"""A project of images with RPCs through the command line, on the real Pléiades triplet (Aubagne)
and the Réunion pair.

Tie points are matched automatically between the images (SIFT, then NCC and
least-squares matching: :func:`prismstation.core.matching.rpc_tiepoints.match_tie_points`) and given to
``new --images`` as a measurements file. ``fit`` then runs with the first image held fixed and
the tie points held to a reference DEM. No DEM covering these crops is among the samples, so
the reference is made from the products' own RPCs: the heights their unbiased intersection
gives the tie points (``report --bias none``), gridded at 5 m with 2 m of noise per node — a DEM
whose common offset to the RPCs is zero. Known answer: the last image's RPC line offset moved
by +30 px and its sample offset by −45 px in the scene file; the fit finds the moves back.
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin
from scipy.interpolate import griddata

from prismstation.cli import main
from prismstation.core.matching.rpc_tiepoints import match_tie_points

pytestmark = pytest.mark.slow   # the matching: ~40 s per block on a busy 2-core machine
SETS = {"triplet": [f"pleiades_triplet/img_0{i}.tif" for i in (1, 2, 3)],
        "reunion": ["pleiades_pair_reunion/img_01.tif", "pleiades_pair_reunion/img_02.tif"]}
H_SIGMA = 2.0
LINE_MOVE, SAMPLE_MOVE = 30.0, -45.0


@pytest.fixture(scope="module", params=list(SETS))
def block(request, shared_data, tmp_path_factory):
    """The project's folder: the tie points' measurements, the project, the reference DEM."""
    d = tmp_path_factory.mktemp(request.param)
    images = [shared_data / f for f in SETS[request.param]]
    arrays = []
    for f in images:
        with rasterio.open(f) as ds:
            arrays.append(ds.read(1))
    tp = match_tie_points(arrays, cell=48)
    with open(d / "ties.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "view", "x", "y", "sigma_px"])
        for j, i, xy, s in zip(tp.point, tp.image, tp.xy, tp.sigma):
            w.writerow([f"T{j:04d}", images[i].stem, float(xy[0]), float(xy[1]), float(s[0])])
    assert main(["new", str(d / "block.prismproj"), "--images", *map(str, images), "--no-ties",
                 "--measurements", str(d / "ties.csv")]) == 0
    # the raw RPCs' report (report's options are its own: the project keeps its shift bias)
    assert main(["report", str(d / "block.prismproj"), "--bias", "none", "-o", str(d / "before.json")]) == 0
    before = json.loads((d / "before.json").read_text())
    _reference_dem(before, d / "dem.tif")
    return d, images, tp


def _reference_dem(report, path):
    """A 5 m GeoTIFF of the tie points' heights (linear between them, nearest outside) + noise;
    ellipsoidal, as the RPCs' are, and the file says so."""
    pts = [p for p in report["points"] if p.get("h_est") is not None]
    en = np.array([(p["E_est"], p["N_est"]) for p in pts])
    h = np.array([p["h_est"] for p in pts])
    x0, y1 = en.min(0)[0] - 200, en.max(0)[1] + 200
    nx, ny = int((en[:, 0].max() + 200 - x0) / 5), int((y1 - en[:, 1].min() + 200) / 5)
    E, N = np.meshgrid(x0 + 2.5 + 5 * np.arange(nx), y1 - 2.5 - 5 * np.arange(ny))
    grid = griddata(en, h, (E, N), method="linear")
    near = griddata(en, h, (E, N), method="nearest")
    grid = np.where(np.isfinite(grid), grid, near) + np.random.default_rng(0).normal(0, H_SIGMA, E.shape)
    with rasterio.open(path, "w", driver="GTiff", width=nx, height=ny, count=1, dtype="float32",
                       crs=report["crs"], transform=from_origin(x0, y1, 5, 5)) as ds:
        ds.write(grid.astype("float32"), 1)
        ds.update_tags(HEIGHTS="ellipsoidal")


def _fit(d, project, out, *extra):
    assert main(["fit", str(d / project), "--fixed-view", "img_01", "--dem", str(d / "dem.tif"),
                 "--dem-sigma", str(H_SIGMA), "--json", str(d / out), *extra]) == 0
    return json.loads((d / out).read_text())


def _tie_rms(report, view):
    return report["statistics"]["image"][view]["TIE"]["px"]


def test_new_writes_a_versioned_rpc_scene(block):
    d, images, tp = block
    scene = json.loads((d / "block.scene.json").read_text())
    assert scene["format"] == "prismstation-scene/2"
    assert list(scene["views"]) == [f.stem for f in images]
    for v in scene["views"].values():
        assert v["model"] == "rpc" and len(v["rpc"]["line_num"]) == 20
    project = json.loads((d / "block.prismproj").read_text())
    assert project["settings"]["bias_model"] == "shift"
    assert len(project["measurements"]) == len(tp.point)


def test_fit_with_one_image_fixed_removes_the_residuals(block, capsys):
    d, images, tp = block
    before = json.loads((d / "before.json").read_text())
    after = _fit(d, "block.prismproj", "after.json")
    bias = after["model"]["bias"]
    assert bias["img_01"]["fixed"] and bias["img_01"]["parameters"] == {}
    assert after["model"]["sensor"] == "rpc"
    assert 0.25 < bias["img_02"]["sigma0"] < 1.0          # the matcher's σ is not optimistic
    for v in (f.stem for f in images):
        b, a = _tie_rms(before, v), _tie_rms(after, v)
        assert a["x"]["n"] == b["x"]["n"] > 100
        print(f"{v}: tie RMS x/y before {b['x']['rms']:.3f}/{b['y']['rms']:.3f} px, "
              f"after {a['x']['rms']:.3f}/{a['y']['rms']:.3f} px")
        assert a["x"]["rms"] < 0.15 and a["y"]["rms"] < 0.15, (v, a)
        # across the lines the raw RPCs disagree by tenths of a pixel; the bias removes it
        assert a["x"]["rms"] < 0.5 * b["x"]["rms"], (v, b, a)
    ties = [p for p in after["points"] if p["kind"] == "TIE"]
    assert all(p["height_source"] == "intersection" for p in ties if "h_est" in p)
    # blunders: points whose largest studentised residual passes 3.29 (normal scale); matched
    # points over relief have a few
    assert sum(p["blunder"] for p in after["points"]) <= 0.05 * len(after["points"])
    # the text report: a column per image
    assert main(["fit", str(d / "block.prismproj"), "--fixed-view", "img_01", "--no-dem"]) == 0
    out = capsys.readouterr().out
    assert "Image residuals per view (px)" in out and images[-1].stem in out
    assert "b0 not determined by the data" in out   # no GCP and no DEM: honest about the line bias


def test_known_offsets_found_back(block):
    """The last image's RPC moved by +30 px along the lines and −45 px across them in the scene
    file: its fitted bias moves by −30 and +45 px, to within its σ."""
    d, images, tp = block
    last = images[-1].stem
    ref = _fit(d, "block.prismproj", "after.json")
    scene = json.loads((d / "block.scene.json").read_text())
    scene["views"][last]["rpc"]["line_off"] += LINE_MOVE
    scene["views"][last]["rpc"]["samp_off"] += SAMPLE_MOVE
    (d / "moved.scene.json").write_text(json.dumps(scene))
    project = json.loads((d / "block.prismproj").read_text())
    project["scene"] = "moved.scene.json"
    (d / "moved.prismproj").write_text(json.dumps(project))
    moved = _fit(d, "moved.prismproj", "moved.json")
    b0, b1 = ref["model"]["bias"][last]["parameters"], moved["model"]["bias"][last]["parameters"]
    for name, move in (("a0", SAMPLE_MOVE), ("b0", LINE_MOVE)):
        found = b1[name]["value"] - b0[name]["value"]
        print(f"{name}: moved {move:+.1f} px, found {-found:+.3f} ± {b1[name]['std']:.3f} px")
        assert abs(found + move) < b1[name]["std"], (name, found, b1[name]["std"])
    # the other images' biases and the residuals do not notice
    for v in (f.stem for f in images):
        for c in "xy":
            assert abs(_tie_rms(moved, v)[c]["rms"] - _tie_rms(ref, v)[c]["rms"]) < 0.01


def test_report_and_refusals(block, capsys):
    d, images, tp = block
    assert main(["report", str(d / "block.prismproj"), "--fixed-view", "img_01", "--dem", str(d / "dem.tif"),
                 "--dem-sigma", "2", "-o", str(d / "report.csv")]) == 0
    rows = list(csv.DictReader(open(d / "report.csv")))
    assert {r["view"] for r in rows} == {f.stem for f in images}
    assert all(r["vx_px"] != "" for r in rows)
    assert main(["fit", str(d / "block.prismproj"), "--bias", "similarity"]) == 2
    assert main(["fit", str(d / "block.prismproj"), "--fixed-view", "N"]) == 2
    assert main(["new", str(d / "one.prismproj"), "--images", str(images[0])]) == 2


def test_dsm_and_orientation_on_the_real_images(block, capsys, tmp_path):
    """``dsm`` at 4 m (8 pixels) through the fitted biases: 80 % of the cells every image sees
    matched (else exit 3), the triplet's pairs agree within 1.5 m NMAD; ``orient-dem`` on the reference made from the raw RPCs' own intersection
    (so the true answer is no shift beyond that DEM's own error): on the triplet the shift found
    is within its σ of zero and is saved as the a-priori biases; on the pair too when the
    co-registration converges (its relative DSM made through the fit that holds the tie points to
    the reference), else it is refused."""
    d, images, tp = block
    proj = tmp_path / "p.prismproj"
    proj.write_bytes((d / "block.prismproj").read_bytes())
    (tmp_path / "block.scene.json").write_bytes((d / "block.scene.json").read_bytes())
    (tmp_path / "dem.tif").write_bytes((d / "dem.tif").read_bytes())
    # the orientation the DSM reads: the tie points held to the reference (stored by fit)
    assert main(["fit", str(proj), "--fixed-view", "img_01", "--dem", str(tmp_path / "dem.tif"),
                 "--dem-sigma", str(H_SIGMA)]) == 0
    capsys.readouterr()
    assert main(["dsm", str(proj), "-o", str(tmp_path / "dsm.tif"), "--posting", "4", "--min-fill", "80"]) == 0
    out = capsys.readouterr().out
    with rasterio.open(tmp_path / "dsm.tif") as ds:
        h = ds.read(1, masked=True)
        assert ds.count == 3 and "ellipsoidal" in ds.crs.to_wkt()
    assert h.count() > 0
    nmads = [float(line.split("NMAD ")[1].split(" m")[0]) for line in out.splitlines() if line.startswith("pairs ")]
    assert len(nmads) == (3 if len(images) == 3 else 0)     # two pair DSMs per comparison
    assert all(v < 1.5 for v in nmads), out
    status = main(["orient-dem", str(proj), str(d / "dem.tif"), "--save", "--json", str(tmp_path / "o.json")])
    c = json.loads((tmp_path / "o.json").read_text())["coregistration"]
    if status == 3:
        # the surface matching may not hold on the pair's reference (145 tie points gridded at
        # 5 m, 2 m of noise per cell): then refused with the reason, nothing stored
        assert len(images) == 2 and not c["converged"] and c["reason"]
        assert "REFUSED" in capsys.readouterr().err
        assert json.loads(proj.read_text()).get("dem_control") is None
        return
    assert status == 0
    s = np.array([c["shift_m"]["dx"], c["shift_m"]["dy"], c["dz"]])
    sig = np.array([c["sigma_m"]["dx"], c["sigma_m"]["dy"], c["sigma_dz"]])
    # the pair's reference holds the block horizontally to its 5 m cell at best (145 tie points
    # tens of metres apart over 2,300 m of relief, gridded linearly): found +2.3, +4.4 m there
    floor = [1.0, 1.0, 1.0] if len(images) == 3 else [5.0, 5.0, 1.0]
    assert np.all(np.abs(s) < np.maximum(4 * sig, floor)), (s, sig)
    assert json.loads(proj.read_text())["dem_control"]["sensor"] == "rpc"
