"""Orthoimages of a simulated triplet (``prismstation simulate``: a rigorous pushbroom geometry, its
true DEM, the exact image positions of its points): the three views agree on the true DEM and
with the truth, a planted bias moves the ortho by exactly that, the DEM's datum, voids, a
window, the file, and the tiles' reads."""
import json
import pickle
from dataclasses import replace

import cv2
import numpy as np
import pytest
import rasterio

from prismstation.core.surfaces.ortho import resample
from prismstation.errors import Cancelled, InputError
from prismstation.io.dem import read_dem, write_dem
from prismstation.io.ortho import read_ortho_info, to_band
from prismstation.io.project import load_project
from prismstation.ops import ortho as ops_ortho
from prismstation.ops import ortho_tiles
from prismstation.ops.fit import solve_project
from prismstation.ops.ortho import OrthoRequest, export_orthos
from prismstation.ops.ortho_validate import validate_ortho
from prismstation.ops.project import create
from prismstation.sim import simulate

GEOID = 55.0      # the simulator's constant geoid (scene.json), the project's


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 500 px triplet oriented on 25 GCPs measured to 0.05 px, surveyed to 0.1 m."""
    d = tmp_path_factory.mktemp("ortho")
    simulate(d, size=500, seed=7, n_gcp=25, n_icp=25, n_tie=10, noise_px=0.05, survey_sigma_xy=0.1,
             survey_sigma_h=0.1)
    create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
    return d


@pytest.fixture(scope="module")
def on_truth(scene):
    """The three views' orthos on the true DEM (ellipsoidal): ``(export, project, solution)``."""
    p = load_project(scene / "p.prismproj")
    sol = solve_project(p)
    out = export_orthos(sol, p, OrthoRequest(str(scene / "t.tif"), ("all",), str(scene / "truth_dem.tif"),
                                             "ellipsoidal"), project_path=scene / "p.prismproj")
    return out, p, sol


def _read(path):
    with rasterio.open(path) as ds:
        return ds.read(1).astype(np.float32), ds.read_masks(1) > 0, ds.transform


def _shift(a, b, r0, c0, size=192):
    """How far ``b``'s content lies from ``a``'s over a window, cells ``(dx, dy)``: b(x + s) = a(x).
    Phase correlation (its peak's centroid leans to whole cells by up to ~0.05), then least
    squares on the gradient with b resampled by cubic convolution, which moves nothing."""
    win = np.s_[r0:r0 + size, c0:c0 + size]
    (dx, dy), _ = cv2.phaseCorrelate(a[win].astype(np.float64), b[win].astype(np.float64),
                                     cv2.createHanningWindow((size, size), cv2.CV_64F))
    s = np.array([dx, dy])
    yy, xx = np.mgrid[r0 + 8:r0 + size - 8, c0 + 8:c0 + size - 8].astype(np.float32)
    ref = a[r0 + 8:r0 + size - 8, c0 + 8:c0 + size - 8]
    for _ in range(6):
        bs = resample(b, xx + np.float32(s[0]), yy + np.float32(s[1]), "cubic")
        gy, gx = np.gradient(bs)
        ok = np.isfinite(bs) & np.isfinite(gx) & np.isfinite(gy)
        A = np.column_stack([gx[ok], gy[ok], np.ones(ok.sum())])
        step = np.linalg.lstsq(A, (ref - bs)[ok], rcond=None)[0][:2]
        s = s + step
        if np.abs(step).max() < 1e-4:
            break
    return s


def _common(paths):
    """The arrays of orthos on one posting cut to their common grid, and the valid cells of all."""
    arrs = [_read(p) for p in paths]
    g = arrs[0][2].a
    x0, y0 = max(t.c for _, _, t in arrs), min(t.f for _, _, t in arrs)
    x1 = min(t.c + g * a.shape[1] for a, _, t in arrs)
    y1 = max(t.f - g * a.shape[0] for a, _, t in arrs)
    w, h = int(round((x1 - x0) / g)), int(round((y0 - y1) / g))
    out = []
    for a, m, t in arrs:
        c0, r0 = int(round((x0 - t.c) / g)), int(round((t.f - y0) / g))
        out.append((a[r0:r0 + h, c0:c0 + w], m[r0:r0 + h, c0:c0 + w]))
    valid = np.logical_and.reduce([m for _, m in out])
    return [a for a, _ in out], valid


def _central_window(valid, size=192):
    r, c = np.nonzero(valid)
    r0, c0 = int(np.median(r)) - size // 2, int(np.median(c)) - size // 2
    assert valid[r0:r0 + size, c0:c0 + size].all()
    return r0, c0


def test_views_agree_on_the_true_dem_and_with_the_truth(scene, on_truth):
    """N, F and B on the true DEM agree with each other to ≤ 0.1 px, and show the points where the
    truth puts them to the orientation's check-point accuracy; the expected σ holds against that
    scatter."""
    out, p, sol = on_truth
    assert [o.view for o in out.orthos] == ["N", "F", "B"]
    arrs, valid = _common([o.path for o in out.orthos])
    r0, c0 = _central_window(valid)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        assert np.abs(_shift(arrs[i], arrs[j], r0, c0)).max() <= 0.1
    truth = json.loads((scene / "truth.json").read_text())["points"]
    for o in out.orthos:
        pts = [(t["id"], t["kind"], (t["E"], t["N"], t["h"]), tuple(t["image"][o.view])) for t in truth
               if t["kind"] == "ICP"]
        val = validate_ortho(sol, p, o.path, points=pts)
        acc = o.accuracy
        icp = val.stats["ICP"]
        assert icp["n"] == 25
        assert icp["rmse_m"] <= acc.check_rmse_m                       # the fit's own check points
        assert 0.3 * acc.expected_sigma_m <= icp["rmse_m"] <= 2.0 * acc.expected_sigma_m
        # what the file shows is what the model says, to a few hundredths of a cell
        d = np.array([np.subtract(c.d, c.predicted) for c in val.points if c.found])
        posting = float(o.tags["ORTHO_POSTING_M"])
        assert np.sqrt(np.mean(d ** 2)) < 0.05 * posting and np.abs(d).max() < 0.25 * posting


def test_a_planted_bias_moves_the_ortho_by_exactly_that(scene, on_truth, tmp_path):
    """Every F measurement moved by (dx, dy) px: the fitted bias takes it, and the F ortho's
    content moves on the ground by −J⁻¹·(dx, dy) (J = ∂(x, y)/∂(E, N)), to 0.01 cell. On flat
    ground (a constant height): over relief the move also follows the slope, J + ∂(x, y)/∂h·∇h."""
    out, p, sol = on_truth
    d = np.array([1.6, -2.3])
    q = load_project(scene / "p.prismproj")
    with q.batch():
        for (pid, view), m in list(q.measurements.items()):
            if view == "F":
                q.set_measurement(replace(m, x=m.x + d[0], y=m.y + d[1]))
    sol2 = solve_project(q)
    flat = dict(views=("F",), height_m=180.0)
    before = export_orthos(sol, p, OrthoRequest(str(tmp_path / "before.tif"), **flat)).orthos[0]
    moved = export_orthos(sol2, q, OrthoRequest(str(tmp_path / "moved.tif"), **flat)).orthos[0]
    (a, b), valid = _common([before.path, moved.path])
    r0, c0 = _central_window(valid)
    g = before.transform[0]
    x0, y0 = max(before.transform[2], moved.transform[2]), min(before.transform[5], moved.transform[5])
    centre = np.array([[x0 + g * (c0 + 96), y0 - g * (r0 + 96)]])
    _, J = sol.model.partials("F", centre, np.array([180.0 + GEOID]))
    dEN = -np.linalg.solve(J[0, :, :2], d)                   # metres east, north
    expected = np.array([dEN[0] / g, -dEN[1] / g])            # cells (columns, rows)
    assert np.hypot(*expected) > 2.0
    assert np.abs(_shift(a, b, r0, c0) - expected).max() <= 0.01


def test_the_dem_datum(scene, on_truth, tmp_path):
    """The true DEM as orthometric heights (no tag: orthometric by convention, a warning), through
    the project's geoid, gives the ortho the ellipsoidal one gives; as a DSM of prismstation's
    saying so in its tag, no warning; the same file taken for what it is not moves an oblique
    view's ortho by about the geoid's 55 m times its off-nadir tangent, and the DEM σ measured at the
    points says so; a geographic copy lands where the projected one does."""
    out, p, sol = on_truth
    g = read_dem(scene / "truth_dem.tif")
    write_dem(tmp_path / "ortho_h.tif", g.heights - GEOID, g.crs, g.transform)
    f = export_orthos(sol, p, OrthoRequest(str(tmp_path / "o.tif"), ("F",), str(tmp_path / "ortho_h.tif")))
    assert any("orthometric" in w for w in f.warnings)
    a, va, _ = _read(out.orthos[1].path)
    b, vb, _ = _read(f.orthos[0].path)
    assert (va == vb).mean() > 0.999 and np.abs(a - b)[va & vb].max() <= 1
    # a file that says its kind
    write_dem(tmp_path / "tagged.tif", g.heights, g.crs, g.transform)
    with rasterio.open(tmp_path / "tagged.tif", "r+") as ds:
        ds.update_tags(HEIGHTS="ellipsoidal")
    tagged = export_orthos(sol, p, OrthoRequest(str(tmp_path / "tg.tif"), ("F",), str(tmp_path / "tagged.tif")))
    assert not tagged.warnings and tagged.orthos[0].tags["ORTHO_DEM_KIND"] == "ellipsoidal"
    # the ellipsoidal heights taken as orthometric: 55 m too high
    wrong = export_orthos(sol, p, OrthoRequest(str(tmp_path / "w.tif"), ("F",), str(scene / "truth_dem.tif"),
                                               "orthometric")).orthos[0]
    assert wrong.accuracy.dem_sigma_m == pytest.approx(GEOID, abs=1.0)
    (a2, c), valid = _common([out.orthos[1].path, wrong.path])
    r0, c0 = _central_window(valid, 128)
    moved = np.hypot(*_shift(a2, c, r0, c0, 128)) * float(wrong.tags["ORTHO_POSTING_M"])
    # (on this relief the move also follows the slopes: J + ∂(x, y)/∂h·∇h, not J alone)
    assert moved == pytest.approx(GEOID * out.orthos[1].accuracy.off_nadir_tan, rel=0.3)
    # geographic: the true DEM carried onto 0.15″ of EPSG:4326 (its bilinear smoothing only)
    from rasterio.warp import calculate_default_transform, reproject, Resampling
    dst_t, w, h = calculate_default_transform(g.crs, "EPSG:4326", g.shape[1], g.shape[0],
                                              *rasterio.transform.array_bounds(g.shape[0], g.shape[1], g.transform),
                                              resolution=0.15 / 3600)
    geo = np.full((h, w), np.nan, np.float32)
    reproject(g.heights.astype(np.float32), geo, src_transform=g.transform, src_crs=g.crs, dst_transform=dst_t,
              dst_crs="EPSG:4326", resampling=Resampling.bilinear, src_nodata=np.nan, dst_nodata=np.nan)
    write_dem(tmp_path / "geo.tif", geo, "EPSG:4326", dst_t)
    gf = export_orthos(sol, p, OrthoRequest(str(tmp_path / "geo_o.tif"), ("F",), str(tmp_path / "geo.tif"),
                                            "ellipsoidal")).orthos[0]
    arrs, valid = _common([out.orthos[1].path, gf.path])
    r0, c0 = _central_window(valid, 128)
    assert np.abs(_shift(arrs[0], arrs[1], r0, c0, 128)).max() <= 0.05


def test_voids_of_the_dem_are_no_data(scene, on_truth, tmp_path):
    out, p, sol = on_truth
    g = read_dem(scene / "truth_dem.tif")
    h = g.heights.copy()
    r, c = h.shape[0] // 2, h.shape[1] // 2
    h[r - 10:r + 10, c - 15:c + 15] = np.nan
    write_dem(tmp_path / "void.tif", h, g.crs, g.transform)
    o = export_orthos(sol, p, OrthoRequest(str(tmp_path / "v.tif"), ("N",), str(tmp_path / "void.tif"),
                                           "ellipsoidal")).orthos[0]
    a, va, t = _read(out.orthos[0].path)
    b, vb, tb = _read(o.path)
    assert tuple(t) == tuple(tb)
    # the hole's ground (5 m DEM cells, bilinear: one cell more) is no data, and nothing else changed
    E = t.c + t.a * (np.arange(a.shape[1]) + 0.5)
    N = t.f + t.e * (np.arange(a.shape[0]) + 0.5)
    hx = (E - g.transform.c) / g.transform.a - 0.5
    hy = (N - g.transform.f) / g.transform.e - 0.5
    inside = ((hy[:, None] > r - 10 - 1) & (hy[:, None] < r + 10) & (hx[None, :] > c - 15 - 1) & (hx[None, :] < c + 15))
    assert inside.sum() > 500
    assert not vb[inside & va].any()
    assert (vb == va)[~inside].all() and (a == b)[~inside & va].all()
    assert (b[~vb] == 0).all()


def test_a_window_gives_every_view_one_grid(scene, on_truth, tmp_path):
    out, p, sol = on_truth
    ex = export_orthos(sol, p, OrthoRequest(str(tmp_path / "w.tif"), ("all",), str(scene / "truth_dem.tif"),
                                            "ellipsoidal", window=(100, 150, 200, 120)))
    grids = {(o.transform, o.shape) for o in ex.orthos}
    assert len(grids) == 1
    (t, shape), = grids
    assert shape[0] * shape[1] < 0.3 * out.orthos[0].shape[0] * out.orthos[0].shape[1]
    # the window's corners, on the ground at their heights, inside the grid
    n = sol.scene.views["N"]
    corners = np.array([[100, 150], [300, 150], [100, 270], [300, 270]], float)
    en = sol.model.image_to_ground("N", corners, sol.mean_height)
    x0, y1 = t[2], t[5]
    x1, y0 = x0 + t[0] * shape[1], y1 + t[4] * shape[0]
    assert ((en[:, 0] > x0 - 100) & (en[:, 0] < x1 + 100) & (en[:, 1] > y0 - 100) & (en[:, 1] < y1 + 100)).all()
    with pytest.raises(InputError, match="outside"):
        export_orthos(sol, p, OrthoRequest(str(tmp_path / "x.tif"), window=(900, 0, 10, 10)))
    assert n.shape == (500, 500)


def test_the_file_is_a_tiled_overviewed_cog_with_a_mask_and_its_metadata(on_truth):
    out, p, sol = on_truth
    o = out.orthos[1]
    info = read_ortho_info(o.path)
    assert info["blocks"] == (256, 256) and info["overviews"] and info["dtype"] == "uint8"
    assert info["nodata"] == 0 and info["mask_flags"] == ["per_dataset"]
    assert info["crs"].to_epsg() == 32629 and info["transform"] == o.transform
    tags = info["tags"]
    assert tags["ORTHO_VIEW"] == "F" and tags["ORTHO_IMAGE"] == "F.tif"
    assert "truth_dem.tif" in tags["ORTHO_DEM"] and tags["ORTHO_DEM_KIND"] == "ellipsoidal"
    assert "GCPs (25 measured in view F)" in tags["ORTHO_ORIENTATION"] and "affine" in tags["ORTHO_ORIENTATION"]
    assert float(tags["ORTHO_EXPECTED_SIGMA_M"]) == pytest.approx(o.accuracy.expected_sigma_m, abs=1e-3)
    assert json.loads(tags["ORTHO_ACCURACY"])["off_nadir_tan"] == pytest.approx(0.5, abs=0.05)
    assert float(tags["ORTHO_INTERPOLATION_MAX_PX"]) <= 0.005
    with rasterio.open(o.path) as ds:
        assert ds.profile["compress"] == "deflate" and ds.profile["tiled"]
        assert ds.read_masks(1, out_shape=(ds.height // 4, ds.width // 4)).any()     # the mask's overviews


def test_no_data_and_a_valid_zero_in_the_band():
    band, mask = to_band(np.array([[np.nan, 0.2, 0.6, 254.7, 300.0, -3.0]], np.float32), "uint8")
    assert band.tolist() == [[0, 1, 1, 255, 255, 1]] and mask.tolist() == [[0, 255, 255, 255, 255, 255]]
    band, mask = to_band(np.array([[np.nan, 1.5]], np.float32), "float32")
    assert np.isnan(band[0, 0]) and band[0, 1] == 1.5 and mask.tolist() == [[0, 255]]


def test_tiles_read_only_the_windows_they_need(scene, on_truth, tmp_path, monkeypatch):
    """Small tiles: every image read is about a tile's footprint, never the image, and each DEM
    read a tile's cells (so memory follows the tile, not the scene); the result is the same."""
    out, p, sol = on_truth
    reads, dems = [], []
    real_read, real_cells = ortho_tiles.ImageWindows.read, ortho_tiles.read_dem_cells

    def read(self, view, c0, r0, w, h, min_px=1):
        reads.append((w, h))
        return real_read(self, view, c0, r0, w, h, min_px)

    def cells(*a, **k):
        grid, t = real_cells(*a, **k)
        dems.append(grid.shape)
        return grid, t
    def tile(spec):                      # the reads of the tiles only (not the accuracy's)
        monkeypatch.setattr(ortho_tiles, "read_dem_cells", cells)
        try:
            return ortho_tiles.run_ortho_tile(spec)
        finally:
            monkeypatch.setattr(ortho_tiles, "read_dem_cells", real_cells)
    monkeypatch.setattr(ortho_tiles.ImageWindows, "read", read)
    monkeypatch.setattr(ops_ortho, "run_ortho_tile", tile)
    monkeypatch.setattr(ops_ortho, "TILE", 128)
    o = export_orthos(sol, p, OrthoRequest(str(tmp_path / "s.tif"), ("F",), str(scene / "truth_dem.tif"),
                                           "ellipsoidal", scheduler="sync")).orthos[0]
    # a tile: 128 cells of 2.5 m, turned 12° (151 px), and the relief's reach in F (up to ~50 px
    # here); the image is 500 px
    assert len(reads) > 12 and max(max(r) for r in reads) < 215
    assert max(max(s) for s in dems) < 80                                    # 320 m of 5 m cells
    a, va, _ = _read(o.path)
    b, vb, _ = _read(out.orthos[1].path)
    # the same to the rounding of a DN (each tile's lattice differs in the 4th decimal of a pixel)
    assert (va == vb).all() and np.abs(a - b).max() <= 1 and (a == b).mean() > 0.99


def test_a_tile_pickles_and_runs_elsewhere_alike(scene, on_truth):
    """What a process or a cluster worker gets: the same tile, the same values."""
    out, p, sol = on_truth
    o = out.orthos[0]
    v = sol.scene.views["N"]
    spec = ortho_tiles.OrthoTile(sol.model, "N", v.image, v.shape, (200, 200, 64, 64), o.transform,
                                 ortho_tiles.Heights(sol.scene.crs, "ellipsoidal", str(scene / "truth_dem.tif")))
    a = ortho_tiles.run_ortho_tile(spec).values
    b = ortho_tiles.run_ortho_tile(pickle.loads(pickle.dumps(spec))).values
    assert np.isfinite(a).all() and np.array_equal(a, b)


def test_without_a_dem_a_constant_height_with_a_warning(scene, on_truth, tmp_path):
    out, p, sol = on_truth
    c = export_orthos(sol, p, OrthoRequest(str(tmp_path / "c.tif"), ("N",), height_m=200.0))
    assert "constant height 200 m" in c.warnings[0] and c.orthos[0].tags["ORTHO_DEM_KIND"] == "orthometric"
    assert c.orthos[0].accuracy.dem_sigma_source.startswith("measured")
    m = export_orthos(sol, p, OrthoRequest(str(tmp_path / "m.tif"), ("N",)))
    assert "mean height" in m.warnings[0]
    with pytest.raises(InputError, match="not a view"):
        export_orthos(sol, p, OrthoRequest(str(tmp_path / "x.tif"), ("Q",)))


def test_without_a_dem_the_projects_reference_dem(scene, on_truth, tmp_path):
    """No DEM named and no constant: the project's own reference DEM, without a warning; a
    constant named still wins over it."""
    out, p, sol = on_truth
    withref = load_project(scene / "p.prismproj")
    withref.reference_dem = str(scene / "truth_dem.tif")
    r = export_orthos(sol, withref, OrthoRequest(str(tmp_path / "r.tif"), ("N",), dem_kind="ellipsoidal"))
    assert not r.warnings
    assert r.orthos[0].tags["ORTHO_DEM_PATH"] == str((scene / "truth_dem.tif").resolve())
    c = export_orthos(sol, withref, OrthoRequest(str(tmp_path / "c.tif"), ("N",), height_m=200.0))
    assert "ORTHO_DEM_PATH" not in c.orthos[0].tags
    with pytest.raises(InputError, match="DEM not found"):
        export_orthos(sol, p, OrthoRequest(str(tmp_path / "x.tif"), dem=str(tmp_path / "none.tif")))


def test_a_cancel_leaves_no_file_and_keeps_an_old_one(scene, on_truth, tmp_path):
    out, p, sol = on_truth
    target = tmp_path / "out" / "keep.tif"
    target.parent.mkdir()
    target.write_bytes(b"old")
    calls = []

    def stop(fraction, message=""):
        calls.append(fraction)
        return fraction < 0.5
    with pytest.raises(Cancelled):
        export_orthos(sol, p, OrthoRequest(str(target), ("N",), str(scene / "truth_dem.tif"), "ellipsoidal"),
                      progress=stop)
    assert target.read_bytes() == b"old" and [f.name for f in target.parent.iterdir()] == ["keep.tif"]
    assert calls == sorted(calls)
