"""JAXA PRISM 1B2 products (CEOS and GeoTIFF) -> scene dict, on byte-exact fixtures."""
from __future__ import annotations

import json
import math
import struct

import numpy as np
import pytest
import rasterio
from pyproj import Transformer
from rasterio.transform import Affine

from prismstation.errors import InputError
from prismstation.io import ceos
from prismstation.io.products import scene_dict_from_product, write_scene_for_product
from tests.io.formats.fixtures import ceos_builder as cb


@pytest.fixture(scope="module")
def triplet(tmp_path_factory):
    root = tmp_path_factory.mktemp("ceos") / "three"
    truth = cb.build_triplet(root)
    return root, truth, scene_dict_from_product(root)


def _apply(m, e, n):
    return m[0] * e + m[1] * n + m[4], m[2] * e + m[3] * n + m[5]


def test_map_to_image_by_hand(triplet):
    _, truth, scene = triplet
    assert scene["crs"] == "EPSG:32629" and set(scene["views"]) == {"N", "F", "B"}
    for letter, t in truth.items():
        m = scene["views"][letter]["map_to_image"]
        a, b, c, d, e, f = t.f4
        # a few ground points around the scene, by hand from the F4 relation: map km from the
        # central meridian (500 km false easting) and the equator, CEOS address 1 at the first
        # pixel's centre -> docs/model.md pixels = address - 0.5
        for E, N in [(585979.86, 4372741.79), (586012.0, 4372700.5), (500000.0, 0.0)]:
            xk, yk = (E - 500000.0) / 1000.0, N / 1000.0
            x_hand = a * xk + b * yk + e - 0.5
            y_hand = c * xk + d * yk + f - 0.5
            x, y = _apply(m, E, N)
            assert x == pytest.approx(x_hand, abs=1e-6) and y == pytest.approx(y_hand, abs=1e-6)
        # the fixture put the common ground point G at each image's centre (F shifted +3 px,
        # B -2 px): 60 x 40 pixels -> (30, 20)
        g = cb.sub_satellite_utm(cb.T_N)
        x, y = _apply(m, *g)
        assert (x, y) == (pytest.approx(30 + {"N": 0, "F": 3, "B": -2}[letter], abs=1e-6),
                          pytest.approx(20.0, abs=1e-6))
        assert scene["views"][letter]["pixel_size_m"] == 2.5
        # the leader's scene-centre position (G, km fields) lands on the image centre
        assert scene["views"][letter]["centre_check_px"] == pytest.approx(
            {"N": 0.0, "F": 3.0, "B": 2.0}[letter], abs=0.01)
        # 2.5 m pixels: one metre east moves 0.4 px along the rotated axes
        assert math.hypot(m[0], m[2]) == pytest.approx(0.4, rel=1e-9)


def test_ground_track_altitude_and_angles(triplet):
    _, truth, scene = triplet
    track = np.array(scene["ground_track"])
    assert len(track) >= 2
    # flight order: a descending pass goes south
    assert track[0, 1] > track[-1, 1]
    # sub-satellite points of the independent truth at the same times (tN - 30 s ... + 30 s)
    times = [cb.T_N + __import__("datetime").timedelta(seconds=s) for s in range(-30, 31, 5)]
    expect = np.array([cb.sub_satellite_utm(t) for t in times])
    assert track.shape == expect.shape
    assert np.max(np.hypot(*(track - expect).T)) < 0.05
    assert scene["satellite_altitude_m"] == pytest.approx(cb.ALT_M, abs=0.05)
    assert scene["views"]["N"]["along_track_angle_deg"] == 0.0
    for letter in "FB":
        got = scene["views"][letter]["along_track_angle_deg"]
        # independent: satellite at the view's time (fixture formula) and G with its normal
        # taken from pyproj (the point 1 m above G minus G)
        g_e, g_n = cb.sub_satellite_utm(cb.T_N)
        lon, lat = Transformer.from_crs(cb.CRS, "EPSG:4326", always_xy=True).transform(g_e, g_n)
        to = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
        g0, g1 = np.array(to.transform(lon, lat, 0.0)), np.array(to.transform(lon, lat, 1.0))
        ray = cb.sat_ecef(truth[letter].time) - g0
        ref = math.degrees(math.acos(ray @ (g1 - g0) / np.linalg.norm(ray) / np.linalg.norm(g1 - g0)))
        assert got == pytest.approx(ref, abs=0.01)   # image centre is 2-3 px from G
        # and a spherical Earth (R = 6371 km) with the ground arc to the sub-satellite point
        arc = math.radians(abs(cb.DLAT) * 45.0) * math.hypot(1.0, 0.012 / 0.0612 * math.cos(
            math.radians(39.5)))
        rh = 6371000.0 + cb.ALT_M
        sph = math.degrees(math.atan2(rh * math.sin(arc), rh * math.cos(arc) - 6371000.0))
        assert got == pytest.approx(sph, abs=0.5)
        assert 26.0 < got < 27.2   # the paper's 26.4 / 26.8 degrees


def test_images_copied_to_geotiff(triplet):
    _, truth, scene = triplet
    for letter, t in truth.items():
        v = scene["views"][letter]
        with rasterio.open(v["image"]) as ds:
            arr = ds.read(1)
            assert arr.dtype == t.image.dtype
            np.testing.assert_array_equal(arr, t.image)
            inv = ~ds.transform
            m = v["map_to_image"]
            assert np.allclose([inv.a, inv.b, inv.d, inv.e, inv.c, inv.f], m, atol=1e-6)
            assert ds.crs.to_epsg() == 32629


def test_one_folder_triplet_and_scene_file(tmp_path):
    truth = cb.build_triplet(tmp_path / "one", one_folder=True)
    scene = scene_dict_from_product(tmp_path / "one")
    assert set(scene["views"]) == {"N", "F", "B"}
    assert scene["times"]["F"].startswith("2007-03-21T11:18:25")
    for letter, t in truth.items():
        assert scene["views"][letter]["scene_id"] == t.scene_id
    out = write_scene_for_product(tmp_path / "one", tmp_path / "proj")
    data = json.loads(out.read_text())
    assert not data["views"]["N"]["image"].startswith("/")
    assert (out.parent / data["views"]["N"]["image"]).resolve().is_file()
    scene_io = pytest.importorskip("prismstation.io.scene")
    sc = scene_io.read_scene(out)        # the project's own scene.json reader accepts it
    assert set(sc.views) == {"N", "F", "B"}


def test_single_view_folder(tmp_path):
    cb.build_triplet(tmp_path / "t")
    one = next((tmp_path / "t").glob("*_UF"))
    scene = scene_dict_from_product(one)
    assert list(scene["views"]) == ["UF"]
    assert scene["views"]["UF"]["along_track_angle_deg"] > 26


def test_geotiff_product(tmp_path):
    """IMG-*.tif + summary.txt: scene dict from the geotransform (rotated) and the summary."""
    folder = tmp_path / "gt"
    folder.mkdir()
    # rotated geotransform: 2.5 m pixels, 10 degrees
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    tr = Affine(2.5 * c, 2.5 * s, 560000.0, 2.5 * s, -2.5 * c, 4400000.0)
    for letter, dt in (("N", 0), ("F", -45), ("B", 45)):
        name = f"IMG-ALPSM{letter}061122750-O1B2R_U{letter}.tif"
        with rasterio.open(folder / name, "w", driver="GTiff", width=50, height=30, count=1,
                           dtype="uint8", crs="EPSG:32629", transform=tr) as ds:
            ds.write(np.full((30, 50), 7, np.uint8), 1)
        (folder / f"RPC-ALPSM{letter}061122750-O1B2R_U{letter}.txt").write_text("rpc\n")
        (folder / f"summary_ALPSM{letter}061122750.txt").write_text(
            f'Scs_SceneID="ALPSM{letter}061122750"\nPds_ProductID="O1B2R_U{letter}"\n'
            f'Img_SceneCenterDateTime="20070321 11:19:{10 + dt // 45 * 5:02d}.000"\n')
    scene = scene_dict_from_product(folder)
    m = scene["views"]["N"]["map_to_image"]
    # pixel (10, 20) by hand: E = 560000 + 2.5c*10 + 2.5s*20, N = 4400000 + 2.5s*10 - 2.5c*20
    E = 560000 + 2.5 * c * 10 + 2.5 * s * 20
    N = 4400000 + 2.5 * s * 10 - 2.5 * c * 20
    assert _apply(m, E, N) == (pytest.approx(10.0, abs=1e-7), pytest.approx(20.0, abs=1e-7))
    assert scene["views"]["N"]["pixel_size_m"] == pytest.approx(2.5)
    assert scene["views"]["B"]["rpc_file"].endswith("RPC-ALPSMB061122750-O1B2R_UB.txt")
    assert scene["times"]["B"] == "2007-03-21T11:19:15+00:00"
    assert scene["satellite_altitude_m"] == ceos.NOMINAL_ALTITUDE_M
    # no state vectors: PRISM's 23.8 deg tilt on a spherical Earth
    assert scene["views"]["F"]["along_track_angle_deg"] == pytest.approx(
        math.degrees(math.asin(7062.65 / 6371.0 * math.sin(math.radians(23.8)))), abs=1e-3)
    # track along the image lines through the centre: direction (2.5 s, -2.5 c) normalised
    tk = np.array(scene["ground_track"])
    d = (tk[-1] - tk[0]) / np.linalg.norm(tk[-1] - tk[0])
    assert d == pytest.approx([s, -c], abs=1e-6)   # track rounded to mm


# ------------------------------------------------------------------ bad products


def _led(root):
    return next(root.glob("*_UN")) / "LED-ALPSMN061122750-O1B2R_UN"


def test_truncated_leader_names_file(tmp_path):
    cb.build_triplet(tmp_path)
    led = _led(tmp_path)
    led.write_bytes(led.read_bytes()[:3000])
    with pytest.raises(InputError) as err:
        scene_dict_from_product(tmp_path)
    assert err.value.file == str(led) and "record" in err.value.problem


def test_blank_zone_and_bad_f4(tmp_path):
    cb.build_triplet(tmp_path)
    led = _led(tmp_path)
    data = bytearray(led.read_bytes())
    mp = 720 + 4680                                  # third record: map projection
    data[mp + 96:mp + 108] = b"  ab        "
    led.write_bytes(bytes(data))
    with pytest.raises(InputError, match="UTM zone") as err:
        scene_dict_from_product(tmp_path)
    assert err.value.file == str(led)
    data[mp + 96:mp + 108] = b"          29"
    data[mp + 1916:mp + 1964] = struct.pack(">6d", 1, 2, 2, 4, 0, 0)   # singular
    led.write_bytes(bytes(data))
    with pytest.raises(InputError, match="F4"):
        scene_dict_from_product(tmp_path)


def test_missing_files_and_bad_summary(tmp_path):
    with pytest.raises(InputError, match="not a JAXA PRISM product"):
        scene_dict_from_product(tmp_path)
    cb.build_triplet(tmp_path / "p")
    summ = next((tmp_path / "p").glob("*_UB")) / "summary.txt"
    summ.write_text('Scs_SceneID="x"\nthis line is wrong\n')
    with pytest.raises(InputError) as err:
        scene_dict_from_product(tmp_path / "p")
    assert err.value.file == str(summ) and err.value.line == 2
    summ.unlink()
    img = next((tmp_path / "p").glob("*_UF")).glob("IMG-*").__next__()
    img.unlink()
    with pytest.raises(InputError, match="no image file"):
        scene_dict_from_product(tmp_path / "p")


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_gdal_ceos_driver_misreads_alos_records(triplet):
    """Why the reader copies CEOS pixels itself: GDAL's CEOS driver opens the file but takes the
    prefix length from another field position, so its pixels differ from the records'."""
    root, truth, _ = triplet
    img = next(root.glob("*_UN")) / "IMG-ALPSMN061122750-O1B2R_UN"
    np.testing.assert_array_equal(np.asarray(ceos.image_array(img)), truth["N"].image)
    try:
        with rasterio.open(img) as ds:
            gdal = ds.read(1)
    except rasterio.errors.RasterioError:
        return
    assert not np.array_equal(gdal, truth["N"].image)
