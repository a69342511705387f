"""simulate(): files in the formats of docs/formats.md, truth consistent with them, determinism, CLI."""
import csv
import json

import numpy as np
import pytest
import rasterio

from prismstation.cli import main
from prismstation.sim import geometry as geo
from prismstation.sim import simulate
from prismstation.sim.run import scene_relief
from prismstation.sim.scenario import build_scenario

SIZE = 640


@pytest.fixture(scope="module")
def triplet(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    seen = []
    paths = simulate(out, size=SIZE, seed=11, n_icp=25, n_tie=8, progress=seen.append)
    assert seen[-1] == 1.0 and all(b >= a for a, b in zip(seen, seen[1:]))
    return out, paths


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _m2i_from_tif(path):
    with rasterio.open(path) as ds:
        inv = ~ds.transform
    return (inv.a, inv.b, inv.d, inv.e, inv.c, inv.f)


def test_images_are_tiled_deflate_uint8_geotiffs(triplet):
    out, paths = triplet
    truth = json.loads((out / "truth.json").read_text())
    for name in "NFB":
        with rasterio.open(paths[name]) as ds:
            assert (ds.width, ds.height, ds.count, ds.dtypes[0]) == (SIZE, SIZE, 1, "uint8")
            assert ds.block_shapes[0] == (512, 512)
            assert ds.compression.value.lower() == "deflate"
            assert ds.crs.to_epsg() == 32629
            t = ds.transform
            assert abs(t.b) > 0.1 and abs(t.d) > 0.1  # rotated: path-oriented 1B2-R
            img = ds.read(1)
            assert 60 < img.mean() < 190 and img.std() > 20
        assert np.allclose(_m2i_from_tif(paths[name]),
                           truth["views"][name]["published_map_to_image"], rtol=0, atol=1e-6)
        # around E 540 km, N 4560 km (geolocation errors up to 50·√2 m, grid shifts 6 px)
        centre = geo.image_to_map(geo.View(name, 0, 0, geo.Attitude(),
                                           tuple(truth["views"][name]["published_map_to_image"])),
                                  np.array([SIZE / 2, SIZE / 2]))
        assert np.allclose(centre, [540000, 4560000], atol=120)


def test_scene_json(triplet):
    out, _ = triplet
    scene = json.loads((out / "scene.json").read_text())
    assert scene["format"] == "prismstation-scene/1" and scene["crs"] == "EPSG:32629"
    assert scene["satellite_altitude_m"] == 691650.0 and scene["geoid_undulation_m"] == 55.0
    angles = {k: v["along_track_angle_deg"] for k, v in scene["views"].items()}
    assert angles == {"N": 0.0, "F": 26.4, "B": 26.8}
    for name, v in scene["views"].items():
        assert (out / v["image"]).exists() and v["pixel_size_m"] == 2.5
        assert "map_to_image" not in v
    track = np.array(scene["ground_track"])
    heading = np.degrees(np.arctan2(*(track[-1] - track[0]))) % 360
    assert heading == pytest.approx(192.0, abs=0.01)  # descending, flight order


def test_points_and_measurements(triplet):
    out, _ = triplet
    pts = _rows(out / "points.csv")
    assert list(pts[0]) == ["id", "E", "N", "H", "kind", "height", "sigma_xy_m", "sigma_h_m"]
    kinds = [p["kind"] for p in pts]
    assert kinds.count("GCP") == 9 and kinds.count("ICP") == 25
    assert {p["height"] for p in pts} == {"orthometric"}
    meas = _rows(out / "measurements.csv")
    assert list(meas[0]) == ["id", "view", "x", "y"]
    assert len(meas) == 3 * (9 + 25 + 8)
    ties = {m["id"] for m in meas} - {p["id"] for p in pts}
    assert len(ties) == 8
    for m in meas:
        assert 0 <= float(m["x"]) <= SIZE and 0 <= float(m["y"]) <= SIZE

    truth = json.loads((out / "truth.json").read_text())
    tp = {p["id"]: p for p in truth["points"]}
    # GCPs well spread: they span most of the image and keep apart
    g = np.array([tp[p["id"]]["image"]["N"] for p in pts if p["kind"] == "GCP"])
    assert np.all(np.ptp(g, axis=0) > 0.45 * SIZE)
    dist = np.hypot(*(g[:, None, :] - g[None, :, :]).transpose(2, 0, 1))
    assert dist[np.triu_indices(9, 1)].min() > 0.12 * SIZE
    # operator noise ~0.3 px, survey noise ~0.5 m / 1.0 m, orthometric = ellipsoidal − 55
    dxy = np.array([[float(m["x"]), float(m["y"])] for m in meas]) - np.array(
        [tp[m["id"]]["image"][m["view"]] for m in meas])
    assert 0.22 < dxy.std() < 0.38 and abs(dxy.mean()) < 0.06
    de = np.array([[float(p["E"]) - tp[p["id"]]["E"], float(p["N"]) - tp[p["id"]]["N"]]
                   for p in pts])
    dh = np.array([float(p["H"]) - (tp[p["id"]]["h"] - 55.0) for p in pts])
    assert 0.3 < de.std() < 0.7 and 0.6 < dh.std() < 1.4


def test_truth_image_coords_follow_from_truth_ground(triplet):
    """truth.json's exact image coordinates are reproduced from its own ground coordinates,
    attitude and grid parameters, and heights lie on truth_dem.tif."""
    out, paths = triplet
    truth = json.loads((out / "truth.json").read_text())
    c = truth["constants"]
    orbit = geo.Orbit(tuple(c["track_origin"]), np.radians(c["heading_deg"]), c["altitude_m"],
                      c["speed_m_s"], c["pixel_m"], c["tan_beta0"], c["col0"])
    enh = np.array([[p["E"], p["N"], p["h"]] for p in truth["points"]])
    for name, v in truth["views"].items():
        view = geo.View(name, v["theta_rad"], v["tau0_s"], geo.Attitude(**v["attitude"]),
                        tuple(v["map_to_image"]))
        xy = geo.image_coords(orbit, view, enh)
        assert np.allclose(xy, [p["image"][name] for p in truth["points"]], atol=1e-6)
    with rasterio.open(paths["truth_dem"]) as ds:
        assert ds.dtypes[0] == "float32" and ds.crs.to_epsg() == 32629
        from scipy.ndimage import map_coordinates
        cols, rows = ~ds.transform @ (enh[:, 0], enh[:, 1])
        dem = ds.read(1)
        h = map_coordinates(dem.astype(float), [rows - 0.5, cols - 0.5], order=1)
        assert np.max(np.abs(h - enh[:, 2])) < 1e-3  # points lie on the bilinear truth DEM
        ortho = dem - 55.0
        relief = scene_relief(SIZE)
        assert ortho.min() < 5.0 and 0.97 * relief < ortho.max() < 1.03 * relief


def test_geolocation_errors_independent_and_as_published(triplet):
    """Each view's published grid is off by its own drawn error at the scene centre (h = 0),
    within the ±50 m default bound; the errors differ between views (no Table 2 constants),
    and F measurements carried into N space through the published affines show the
    across-track offset truth.json states."""
    from prismstation.sim.perturb import truth_geometry
    from prismstation.sim.scenario import geolocation_error_at
    out, _ = triplet
    truth = json.loads((out / "truth.json").read_text())
    orbit, views, size = truth_geometry(truth)
    errs = {}
    for name, view in views.items():
        e = truth["views"][name]["geolocation_error_m"]
        assert abs(e["along"]) <= 50 and abs(e["across"]) <= 50
        got = geolocation_error_at(orbit, view, truth["views"][name]["published_map_to_image"],
                                   np.array([size / 2, size / 2]))
        assert np.allclose(got, [e["E"], e["N"]], atol=1e-6)
        assert np.hypot(*(got - (e["along"] * orbit.t + e["across"] * orbit.a))) < 1e-6
        errs[name] = np.array([e["along"], e["across"]])
    assert min(np.hypot(*(errs[a] - errs[b])) for a, b in ("NF", "NB", "FB")) > 1.0
    m2i = {k: v["published_map_to_image"] for k, v in truth["views"].items()}

    def to_n(view, xy):
        a1, a2, a3, a4, a5, a6 = m2i[view]
        en = np.linalg.solve([[a1, a2], [a3, a4]], np.asarray(xy).T - [[a5], [a6]]).T
        b1, b2, b3, b4, b5, b6 = m2i["N"]
        return en @ np.array([[b1, b3], [b2, b4]]) + [b5, b6]

    n = np.array([p["image"]["N"] for p in truth["points"]])
    for view in "FB":
        dx = to_n(view, [p["image"][view] for p in truth["points"]])[:, 0] - n[:, 0]
        stated = truth["statistics"][f"across_{view}_minus_N_px"]["mean"]
        # 1B2-R: +y is the flight direction, so the across component is x
        assert dx.mean() == pytest.approx(stated, abs=0.05)
        # the difference of the drawn across-track errors, in pixels, up to drift and yaw
        expect = (errs[view][1] - errs["N"][1]) / 2.5
        assert stated == pytest.approx(expect, abs=1.0), (view, stated, expect)


def test_perturbed_scene_has_the_requested_errors(triplet, tmp_path):
    """One rendering, many geolocations: the perturbed scene file reads as a scene, points at
    the same images and its grids carry exactly the requested errors."""
    from prismstation.io.scene import read_scene
    from prismstation.sim.perturb import perturb_geolocation, truth_geometry
    from prismstation.sim.scenario import geolocation_error_at
    out, _ = triplet
    want = {"N": (100.0, 0.0), "F": (-70.7, 70.7), "B": (0.0, -100.0)}
    path = perturb_geolocation(out, want, tmp_path / "sub" / "scene_100.json")
    scene = read_scene(path)
    truth = json.loads((out / "truth.json").read_text())
    orbit, views, size = truth_geometry(truth)
    for name, (along, across) in want.items():
        v = scene.views[name]
        assert v.image == str((out / f"{name}.tif").resolve())
        m = v.map_to_image.matrix
        coeffs = (m[0, 0], m[0, 1], m[1, 0], m[1, 1], m[0, 2], m[1, 2])
        got = geolocation_error_at(orbit, views[name], coeffs, np.array([size / 2, size / 2]))
        assert np.allclose(got, along * orbit.t + across * orbit.a, atol=1e-6), name
    with pytest.raises(ValueError):
        perturb_geolocation(out, {"N": (0, 0)}, tmp_path / "x.json")


def test_deterministic_by_seed(tmp_path):
    a = simulate(tmp_path / "a", size=300, seed=4, n_icp=5, n_tie=2)
    b = simulate(tmp_path / "b", size=300, seed=4, n_icp=5, n_tie=2)
    c = simulate(tmp_path / "c", size=300, seed=5, n_icp=5, n_tie=2)
    for key in ("points", "measurements", "truth"):
        assert a[key].read_text() == b[key].read_text()
        assert a[key].read_text() != c[key].read_text()
    for key in ("N", "F", "B", "truth_dem"):
        with rasterio.open(a[key]) as ra, rasterio.open(b[key]) as rb, rasterio.open(c[key]) as rc:
            assert np.array_equal(ra.read(1), rb.read(1))
            assert not np.array_equal(ra.read(1), rc.read(1))


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_north_up_ascending_map_to_image_in_json(tmp_path):
    p = simulate(tmp_path, size=300, seed=2, n_icp=4, n_tie=0, north_up=True, ascending=True,
                 map_to_image_in_json=True, survey_sigma_xy=0, survey_sigma_h=0, noise_px=0)
    scene = json.loads(p["scene"].read_text())
    truth = json.loads(p["truth"].read_text())
    assert scene["pass"] == "ascending" and scene["product_level"] == "1B2G"
    track = np.array(scene["ground_track"])
    assert np.degrees(np.arctan2(*(track[-1] - track[0]))) % 360 == pytest.approx(348, abs=0.01)
    for name, v in scene["views"].items():
        a1, a2, a3, a4 = v["map_to_image"][:4]
        assert (a1, a2, a3, a4) == (0.4, 0.0, 0.0, -0.4)
        assert v["map_to_image"] == truth["views"][name]["published_map_to_image"]
        with rasterio.open(p[name]) as ds:
            assert ds.crs is None and ds.transform.is_identity
    tp = {q["id"]: q for q in truth["points"]}
    for row in _rows(p["points"]):
        assert float(row["E"]) == pytest.approx(tp[row["id"]]["E"], abs=1e-3)
        assert float(row["H"]) == pytest.approx(tp[row["id"]]["h"] - 55.0, abs=1e-3)
    for row in _rows(p["measurements"]):
        assert float(row["x"]) == pytest.approx(tp[row["id"]]["image"][row["view"]][0], abs=1e-4)


def test_cli_writes_and_rejects_bad_arguments(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "o"), "--size", "300", "--icp", "3", "--ties", "1",
                 "--quiet", "--seed", "9", "--geolocation-error-m", "100"]) == 0
    assert (tmp_path / "o" / "scene.json").exists()
    capsys.readouterr()
    for bad in (["--size", "abc"], ["--size", "10"], ["--noise-px", "-1"], ["--pass", "sideways"],
                ["--gcp", "-2"], ["--geolocation-error-m", "-5"], ["--geolocation-error-m", "nan"]):
        with pytest.raises(SystemExit) as exc:
            code = main(["simulate", str(tmp_path / "x")] + bad)
            raise SystemExit(code)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    (tmp_path / "file").write_text("x")
    assert main(["simulate", str(tmp_path / "file"), "--quiet"]) == 2


def test_large_products_get_internal_overviews(tmp_path):
    """The writer used for > 4096 px images: windows written block by block, then internal
    (not .ovr) deflate overviews down to ~minimum px."""
    from prismstation.sim import writer
    path = tmp_path / "big.tif"
    gt = (500000.0, 2.0, 0.5, 4560000.0, 0.5, -2.0)
    with writer.product_writer(path, 1024, gt, "EPSG:32629") as write:
        for r0 in range(0, 1024, 256):
            write(np.full((256, 1024), r0 // 256 * 50, np.uint8), r0)
    assert writer.add_overviews(path, 1024, minimum=128) == [2, 4, 8]
    assert not (tmp_path / "big.tif.ovr").exists()
    with rasterio.open(path) as ds:
        assert ds.overviews(1) == [2, 4, 8]
        assert ds.transform.to_gdal() == pytest.approx(gt)
        small = ds.read(1, out_shape=(128, 128))
        assert small[0, 0] == 0 and small[-1, 0] == 150


def _image(path):
    with rasterio.open(path) as ds:
        return ds.read(1).astype(float)


def test_rendering_options_alias_block_and_bend(tmp_path, capsys):
    """The options for what another renderer differs by: defaults render as before (the same
    images as without the options); flat parcels sampled at one point per pixel have hard
    edges (neighbours differing by more than 30 DN) where the default point spread softens
    them; JPEG adds steps at the 8 × 8 block borders; an attitude acceleration moves the
    images' points by a curve in time that a drift cannot (each view's true positions differ
    from the linear-attitude scene's by more than a line in time, the other draws kept)."""
    kw = dict(size=256, seed=4, n_icp=4, n_tie=0, noise_px=0.0, terrain="smooth")
    base = simulate(tmp_path / "base", **kw)
    same = simulate(tmp_path / "same", psf_px=0.6, noise_dn=1.2, texture="fields", attitude_accel=0.0,
                    jpeg_quality=None, **kw)
    assert np.array_equal(_image(base["N"]), _image(same["N"]))
    sharp = simulate(tmp_path / "sharp", texture="parcels", psf_px=0.0, noise_dn=2.0, **kw)
    soft = simulate(tmp_path / "soft", texture="parcels", **kw)

    def hard_edges(img):
        return np.mean(np.abs(np.diff(img, axis=1)) > 30)
    assert hard_edges(_image(sharp["N"])) > 2 * hard_edges(_image(soft["N"]))
    jpeg = simulate(tmp_path / "jpeg", jpeg_quality=30, **kw)
    d = _image(jpeg["N"]) - _image(base["N"])
    step = np.abs(np.diff(d, axis=1))
    at_border = step[:, 7::8].mean()
    inside = np.delete(step, np.s_[7::8], axis=1).mean()
    assert at_border > 1.3 * inside
    linear = build_scenario(np.random.default_rng(7), 6000)
    bent = build_scenario(np.random.default_rng(7), 6000, attitude_accel=5e-7)
    tau = np.linspace(-8.0, 8.0, 33)
    for view in "NFB":
        a0, a1 = linear.views[view].attitude, bent.views[view].attitude
        assert a1.pitch_rate == a0.pitch_rate and a1.roll == pytest.approx(a0.roll, abs=1e-8)  # same draws
        d = np.array(a1.angles(tau)[:2]) - np.array(a0.angles(tau)[:2])
        line = np.polynomial.polynomial.polyfit(tau, d.T, 1)
        bend = d.T - np.polynomial.polynomial.polyval(tau, line).T
        assert np.abs(bend).max() > 1e-6, view                            # rad: 0.7 m at 690 km
    assert main(["simulate", str(tmp_path / "x"), "--psf-px", "-1", "--quiet"]) == 2
    assert "--psf-px" in capsys.readouterr().err


def test_mottled_parcels_are_larger_fainter_and_grained_inside():
    """``texture="mottled"`` (another renderer's parcels as measured): parcels further apart and
    of less contrast than ``parcels``, and inside them a grain of a few metres where flat
    parcels hold only their slow modulation."""
    from scipy import ndimage

    from prismstation.sim.texture import MOTTLED, ParcelTexture
    e, n = np.meshgrid(np.arange(0.0, 2000.0, 2.5), -np.arange(0.0, 2000.0, 2.5))
    out = {}
    for kind, kw in (("parcels", {}), ("mottled", MOTTLED)):
        img = ParcelTexture(np.random.default_rng(3), (0.0, 0.0), **kw)(e, n).astype(float)
        edge = np.hypot(ndimage.sobel(img, 0), ndimage.sobel(img, 1)) / 8 > 5
        inside = ~ndimage.binary_dilation(edge, iterations=6)
        grain = ndimage.gaussian_filter(img, 0.7) - ndimage.gaussian_filter(img, 2)
        starts = [np.flatnonzero(np.diff(row.astype(int)) == 1) for row in edge[::20]]
        out[kind] = (np.median(np.concatenate([np.diff(s) for s in starts])),
                     ndimage.median_filter(img[::2, ::2], 9).std(), grain[inside].std())
    (gap0, spread0, grain0), (gap1, spread1, grain1) = out["parcels"], out["mottled"]
    assert gap1 > 1.3 * gap0 and spread1 < 0.75 * spread0, out
    assert grain1 > 0.6 and grain1 > 2 * grain0, out
