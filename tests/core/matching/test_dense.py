"""Dense parallax from a synthetic F/B pair made from real texture with a known parallax field."""
import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.core.matching.dense import heights_from_parallax, parallax_map


def py_true(x, y):
    """Known smooth parallax field (N-image pixels) at N coordinates."""
    return (4 * np.exp(-((x - 200) ** 2 + (y - 210) ** 2) / (2 * 70 ** 2))
            - 3 * np.exp(-((x - 100) ** 2 + (y - 300) ** 2) / (2 * 50 ** 2)) + 0.004 * x)


@pytest.fixture(scope="module")
def texture(shared_data):
    with rasterio.open(shared_data / "pleiades_triplet" / "img_03.tif") as ds:
        t = ds.read(1, window=((0, 800), (0, 800))).astype(float)
    return ndimage.spline_filter(ndimage.gaussian_filter(t, 1.0)[::2, ::2], 3)


def render(coeffs, sign, d, offset, field=py_true):
    """View image whose pixel at view coords q shows the ground point at N position pN, with
    q + offset = pN + sign·py(pN)/2·d (so F − B = py along d, midpoint at N); ``py = field``."""
    rows, cols = coeffs.shape
    jj, ii = np.mgrid[0:rows, 0:cols].astype(float)
    qx, qy = ii + 0.5 + offset[0], jj + 0.5 + offset[1]
    px, py = qx.copy(), qy.copy()
    for _ in range(40):
        p = field(px, py)
        px, py = qx - sign * p / 2 * d[0], qy - sign * p / 2 * d[1]
    return ndimage.map_coordinates(coeffs, [py - 0.5, px - 0.5], order=3, prefilter=False,
                                   mode="reflect").astype(np.float32)


@pytest.mark.parametrize("angle", [0.0, 20.0])
def test_parallax_field_is_recovered(texture, angle):
    d = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle))])
    f = render(texture, +1, d, (0.0, 0.0))
    b = render(texture, -1, d, (3.0, -2.0))          # B array coords + (3, -2) = N coords
    calls = []
    r = parallax_map(f, b, [[1, 0, 0], [0, 1, 0]], [[1, 0, 3.0], [0, 1, -2.0]],
                     (50, 40, 300, 320), d, search_range=8, block_rows=100,
                     progress=lambda x: calls.append(x) or True)
    assert r.parallax.shape == (320, 300) and not r.cancelled
    jj, ii = np.mgrid[0:320, 0:300]
    err = r.parallax - py_true(ii + 50.5, jj + 40.5)
    assert r.valid_fraction > 0.9
    assert np.sqrt(np.nanmean(err ** 2)) < 0.2           # measured ~0.06 px
    assert abs(np.nanmean(err)) < 0.05
    assert calls[-1] == pytest.approx(1.0) and len(calls) >= 3


def test_prior_shifts_the_search_and_cancel_stops(texture):
    d = np.array([1.0, 0.0])
    f = render(texture, +1, d, (0.0, 0.0))
    b = render(texture, -1, d, (0.0, 0.0))
    # a true parallax beyond the search range is missed without a prior, found with it
    b_far = np.roll(b, -10, axis=1)                     # B content 10 px further left: py + 10
    win = (60, 60, 200, 200)
    miss = parallax_map(f, b_far, np.eye(2, 3), np.eye(2, 3), win, d, search_range=7)
    hit = parallax_map(f, b_far, np.eye(2, 3), np.eye(2, 3), win, d, search_range=7, prior=10.0)
    jj, ii = np.mgrid[0:200, 0:200]
    # a point's midpoint pF − py/2 moved by −10/2 px along x with the extra 10 px of parallax
    truth = py_true(ii + 60.5 + 5, jj + 60.5) + 10
    assert miss.valid_fraction < 0.3
    assert hit.valid_fraction > 0.8
    assert np.nanmedian(np.abs(hit.parallax - truth)) < 0.3
    stop = parallax_map(f, b, np.eye(2, 3), np.eye(2, 3), win, d, block_rows=50,
                        progress=lambda x: False)
    assert stop.cancelled and stop.valid_fraction < 0.5


def test_the_prior_is_taken_where_f_sees_the_point(texture):
    """A large parallax (relief) varying fast along the flight direction, the exact prior on the
    N grid and a narrow search: F's pixel at u shows the point N sees at u − w·py, 30 px away
    here, and the prior must be read there (read at u it was up to 9 px off: misses and bias)."""
    d = np.array([1.0, 0.0])
    steep = lambda x, y: 60.0 + 8.0 * np.sin(x / 25.0) + 0.0 * y  # noqa: E731
    f = render(texture, +1, d, (0.0, 0.0), steep)
    b = render(texture, -1, d, (0.0, 0.0), steep)
    win = (80, 60, 200, 200)
    jj, ii = np.mgrid[0:200, 0:200]
    truth = steep(ii + 80.5, jj + 60.5)
    r = parallax_map(f, b, np.eye(2, 3), np.eye(2, 3), win, d, search_range=3, prior=truth)
    err = r.parallax - truth
    assert r.valid_fraction > 0.7                       # measured 0.78 (0.21 with the prior read at u)
    assert np.sqrt(np.nanmean(err ** 2)) < 0.2 and abs(np.nanmean(err)) < 0.05  # 0.09 px (1.0 px)


def test_flat_images_give_nan_and_heights_follow_the_line():
    flat = np.full((120, 120), 7.0, np.float32)
    r = parallax_map(flat, flat, np.eye(2, 3), np.eye(2, 3), (20, 20, 60, 60), (0, 1))
    assert r.valid_fraction == 0.0
    h = heights_from_parallax(np.array([0.0, 10.0, np.nan]), 100.0, 2.496)
    assert h[0] == 100.0 and h[1] == pytest.approx(124.96) and np.isnan(h[2])


# ---------------------------------------------------------------- the DSM engine
from prismstation.core.matching import sgm  # noqa: E402
from prismstation.errors import Cancelled  # noqa: E402


def test_search_range_covers_the_stated_uncertainty():
    for R, k, g in ((600.0, 0.88, 40.0), (25.0, 0.44, 2.5), (1.0, 0.88, 2.5)):
        lo, n = sgm.disparity_search(R, k, g)
        assert n % 16 == 0 and lo <= -k * R / g - 1 and lo + n - 2 >= k * R / g


def test_fusion_drops_the_blunder_and_leaves_disagreement_void():
    v = np.array([[[10.0, 10.0, 10.0, np.nan]], [[10.4, 10.4, 30.0, 5.0]], [[10.2, 60.0, np.nan, np.nan]]])
    s = np.array([1.0, 1.0, 0.5])
    h, q = sgm.fuse(v, s, tau=3.0)
    # cell 0: all agree, weighted towards the σ 0.5 value; cell 1: 60 m removed, not averaged
    assert q[0, 0] == 3 and h[0, 0] == pytest.approx((10 + 10.4 + 4 * 10.2) / 6, abs=1e-5)
    assert q[0, 1] == 2 and h[0, 1] == pytest.approx(10.2, abs=1e-5)
    # two values 20 m apart: no way to tell which is right → void; a single value → void here
    assert q[0, 2] == 0 and np.isnan(h[0, 2]) and q[0, 3] == 0 and np.isnan(h[0, 3])


def test_sgbm_and_refinement_recover_a_known_disparity(texture):
    left = (texture[:300, :300] - texture.min()) / np.ptp(texture) * 255
    yy, xx = np.mgrid[0:300, 0:300].astype(np.float32)
    d_true = 3.3 + 2.0 * np.sin(xx / 60.0) * np.cos(yy / 80.0)
    # right(x − d) = left(x): right sampled at x + d(x)
    right = ndimage.map_coordinates(left, [yy, xx + d_true], order=3, mode="reflect")
    lo, n = sgm.disparity_search(8.0, 1.0, 1.0)
    d = sgm.sgbm(left.astype(np.uint8), right.astype(np.uint8), lo, n)
    r = sgm.refine_subpixel(left.astype(np.float32), right.astype(np.float32), d)
    inner = (slice(20, -20), slice(40, -20))
    e_raw, e_ref = (d - d_true)[inner], (r - d_true)[inner]
    assert np.isfinite(e_raw).mean() > 0.9
    rms = lambda e: float(np.sqrt(np.nanmean(e ** 2)))  # noqa: E731
    assert rms(e_raw) < 0.4 and rms(e_ref) < 0.25 and rms(e_ref) < rms(e_raw)   # measured 0.21 → 0.09


@pytest.fixture(scope="module")
def triplet(tmp_path_factory):
    """A small simulated triplet (700 px, 1.75 km), its project, fitted model and truth."""
    from prismstation.ops.project import create
    from prismstation.io.project import load_project
    from prismstation.ops.fit import solve_project
    from prismstation.sim import simulate
    d = tmp_path_factory.mktemp("dsm")
    simulate(d, size=700, seed=5)
    create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
    project = load_project(d / "p.prismproj")
    return d, project, solve_project(project)


@pytest.fixture(scope="module")
def dsm10(triplet):
    from prismstation.ops.dsm import make_dsm
    calls = []
    d = make_dsm(triplet[2], posting_m=10.0, progress=lambda f, m="": calls.append(f) or True)
    return d, calls


def _truth_on(d, folder):
    from prismstation.io.dem import read_dem
    return read_dem(folder / "truth_dem.tif", d.crs, d.transform, d.heights.shape,
                    resampling="bilinear").heights


def test_dsm_meets_accuracy_and_density_on_a_simulated_triplet(triplet, dsm10):
    d, calls = dsm10
    e = (d.heights - _truth_on(d, triplet[0]))[d.seen & np.isfinite(d.heights)]
    nmad = 1.4826 * np.median(np.abs(e - np.median(e)))
    assert d.fill_fraction > 0.95 and d.seen.mean() > 0.5
    assert nmad < 1.5 and np.sqrt(np.mean(e ** 2)) < 3.0          # measured 0.96 / 1.21 m at 10 m
    assert set(np.unique(d.mask)) <= {0, 1} and d.quality[d.mask == 1].min() >= 1
    assert calls[-1] == 1.0 and all(b >= a for a, b in zip(calls, calls[1:]))


def test_local_cluster_gives_the_same_dsm(triplet, dsm10):
    from distributed import Client, LocalCluster

    from prismstation.ops.dsm import make_dsm
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        d = make_dsm(triplet[2], posting_m=10.0, scheduler=client)
    assert np.array_equal(d.heights, dsm10[0].heights, equal_nan=True)
    assert np.array_equal(d.quality, dsm10[0].quality)


def test_cancel_stops_the_dsm(triplet):
    from prismstation.ops.dsm import make_dsm
    seen = []
    with pytest.raises(Cancelled):
        make_dsm(triplet[2], posting_m=20.0, progress=lambda f, m="": seen.append(f) or len(seen) < 3)
    assert len(seen) == 3


def test_geotiff_reads_back_with_vertical_crs_overviews_and_bands(triplet, dsm10, tmp_path):
    from dataclasses import replace

    from prismstation.io.dsm import read_dsm_info, write_dsm
    d = dsm10[0]
    write_dsm(tmp_path / "e.tif", d)
    info = read_dsm_info(tmp_path / "e.tif")
    assert info["crs"].is_compound and len(info["crs"].axis_info) == 3
    assert "ellipsoidal" in info["crs"].sub_crs_list[1].name
    assert info["blocks"] == (256, 256) or min(d.heights.shape) < 256
    assert info["bands"] == ("height", "mask", "pairs_agreeing") and np.isnan(info["nodata"])
    assert float(info["tags"]["FILL_PERCENT"]) == pytest.approx(100 * d.fill_fraction, abs=0.01)
    assert not list(tmp_path.glob("*.aux.xml")) and not list(tmp_path.glob(".dsm-*"))
    with rasterio.open(tmp_path / "e.tif") as ds:
        h = ds.read(1, masked=True)
        assert np.allclose(h.filled(np.nan), d.heights, equal_nan=True)
    # orthometric: compound with the geoid's vertical CRS; overviews on a grid big enough
    big = replace(d, heights=np.kron(d.heights, np.ones((4, 4), np.float32)), mask=np.kron(d.mask, np.ones((4, 4), np.uint8)),
                  seen=np.kron(d.seen, np.ones((4, 4), bool)), quality=np.kron(d.quality, np.ones((4, 4), np.uint8)),
                  height_kind="orthometric", geoid="grid egm96_15.gtx")
    write_dsm(tmp_path / "o.tif", big)
    info = read_dsm_info(tmp_path / "o.tif")
    assert info["crs"].is_compound and info["crs"].sub_crs_list[1].to_epsg() == 5773
    assert info["overviews"] and info["blocks"] == (256, 256)


def test_cli_exits_non_zero_below_the_fill_threshold(triplet, tmp_path, capsys):
    from prismstation.cli import main
    folder = triplet[0]
    out = tmp_path / "d.tif"
    rc = main(["dsm", str(folder / "p.prismproj"), "-o", str(out), "--posting", "20", "--min-fill", "100.1",
               "--fill"])
    err = capsys.readouterr().err
    assert rc == 3 and "LOW FILL" in err and out.exists()
    assert main(["dsm", str(folder / "p.prismproj"), "-o", str(out), "--posting", "20", "--min-fill", "50"]) == 0
    said = capsys.readouterr().out
    assert "heights: the" in said and "leave-one-out over 9 GCPs" in said   # auto: the GCPs chose


def test_cli_heights_model_as_asked_and_tagged(triplet, tmp_path, capsys):
    """``--heights line`` and ``rays`` differ by the model's height correction; the GeoTIFF
    says which it holds."""
    import rasterio
    from prismstation.cli import main
    from prismstation.io.dsm import read_dsm_info
    folder = triplet[0]
    h = {}
    for m in ("line", "rays"):
        out = tmp_path / f"{m}.tif"
        assert main(["dsm", str(folder / "p.prismproj"), "-o", str(out), "--posting", "20", "--heights", m]) == 0
        assert read_dsm_info(out)["tags"]["HEIGHT_MODEL"] == f"{m} ({m} as asked)"
        with rasterio.open(out) as ds:
            h[m] = ds.read(1, masked=True).filled(np.nan)
    d = h["line"] - h["rays"]
    assert np.isfinite(d).mean() > 0.5 and 0.01 < np.nanmax(np.abs(d)) < 5.0
    with pytest.raises(SystemExit):
        main(["dsm", str(folder / "p.prismproj"), "-o", str(tmp_path / "x.tif"), "--heights", "plane"])
    assert "invalid choice" in capsys.readouterr().err


def test_reference_prior_and_void_filling(triplet):
    """A reference DEM narrows the search (fewer levels) and filled voids are marked 2."""
    from prismstation.io.dem import read_dem
    from prismstation.ops.dsm import MASK_FILLED, MASK_MATCHED, make_dsm
    folder, _, sol = triplet
    ref = read_dem(folder / "truth_dem.tif")
    ref_h = ref.heights + np.random.default_rng(1).normal(0, 5, ref.heights.shape)   # a noisy reference
    d = make_dsm(sol, posting_m=20.0, reference=(ref_h, tuple(ref.transform)[:6]), height_uncertainty_m=30.0,
                 fill=True)
    assert len(d.info["levels"]) < 4 and d.info["height_uncertainty_m"] == 30.0
    filled = d.mask == MASK_FILLED
    assert filled.any() and np.isfinite(d.heights[filled]).all() and not (filled & ~d.seen).any()
    assert np.isfinite(d.heights[d.seen]).all() and d.fill_fraction == pytest.approx(
        (d.mask[d.seen] == MASK_MATCHED).mean())
    e = (d.heights - _truth_on(d, folder))[d.mask == MASK_MATCHED]
    assert 1.4826 * np.median(np.abs(e - np.median(e))) < 2.5


def test_dsm_heights_follow_the_fitted_models_parallax_line(triplet):
    """The correction turns the matching's geometric height into the model's (F–B parallax
    line) height anywhere in the scene and at any height, not only on its lattice."""
    from prismstation.core.models import prism
    from prismstation.core.surfaces.dsm_heights import model_height_correction
    _, _, sol = triplet
    sc = sol.scene
    corr = model_height_correction(sol, 300.0, 900.0)
    rng = np.random.default_rng(0)
    rows, cols = sc.views["N"].shape
    xy = rng.uniform(0, 1, (50, 2)) * (cols, rows)
    hh = rng.uniform(250.0, 950.0, 50)
    en = sol.image_to_ground("N", xy, hh)
    T = {v: prism.to_nadir_space(sc, sc.views[v]) for v in "FB"}
    f, b = T["F"](sol.ground_to_image("F", en, hh)), T["B"](sol.ground_to_image("B", en, hh))
    py = np.einsum("ij,ij->i", f - b, prism.along_track_unit(sc, prism.image_to_map(sc.views["N"])((f + b) / 2)))
    line = sol.model.parallax.height(py)
    assert np.abs(hh + corr(en, hh) - line).max() < 0.01
    assert np.abs(line - hh).max() > 0.05          # the two geometries do differ on this scene


def test_export_cancelled_while_writing_leaves_the_old_file_and_no_other(triplet, tmp_path):
    """The one DSM export (command and window): a cancel after the computation, during the
    write, leaves an existing output as it was and no temporary beside it."""
    from prismstation.ops.dsm_export import DsmRequest, export_dsm
    out = tmp_path / "dsm.tif"
    out.write_bytes(b"the previous DSM")
    msgs = []

    def progress(f, m=""):
        msgs.append(m)
        return m != "written"                  # stop once the file is written, before it is kept
    with pytest.raises(Cancelled):
        export_dsm(triplet[2], triplet[1], DsmRequest(str(out), posting_m=20.0), progress=progress)
    assert "writing" in msgs and out.read_bytes() == b"the previous DSM"
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".") or p.suffix == ".part"]
    res = export_dsm(triplet[2], triplet[1], DsmRequest(str(out), posting_m=20.0, min_fill_percent=101.0))
    assert res.low_fill and res.dsm.posting_m == 20.0 and res.fill_percent == pytest.approx(100 * res.dsm.fill_fraction)
    with rasterio.open(out) as ds:
        assert ds.transform.a == 20.0
