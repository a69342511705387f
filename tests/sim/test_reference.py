"""The simulator's geographic reference DEM: SRTM's grid (3″ EPSG:4326, posts on multiples of
3″), orthometric through the EGM96 grid, the truth's cell means where they belong, noise and
voids as stated; ``simulate --reference``'s bad input refused before anything is written."""
import numpy as np
import pytest
import rasterio

from prismstation.cli import main
from prismstation.io.geoid import GridGeoid, find_grid
from prismstation.ops.coregister import coregister_dems
from prismstation.sim.reference import SRTM_VOID, make_geographic_reference

STEP = 3 / 3600


@pytest.fixture(scope="module")
def geoid():
    g = find_grid()
    if g is None:
        pytest.skip("no EGM96 grid on PROJ's data paths (packaging/setup.sh installs proj-data)")
    return GridGeoid(g)


@pytest.fixture(scope="module")
def scene(tmp_path_factory, geoid):
    out = tmp_path_factory.mktemp("geo_ref")
    assert main(["simulate", str(out), "--size", "640", "--seed", "3", "--icp", "5", "--ties",
                 "2", "--reference", "geographic", "--quiet"]) == 0
    return out


def test_the_reference_is_on_srtms_grid_with_its_noise_and_voids(scene, geoid):
    with rasterio.open(scene / "srtm.tif") as ds:
        t, data = ds.transform, ds.read(1)
        assert ds.crs.to_epsg() == 4326 and ds.dtypes[0] == "int16" and ds.nodata == SRTM_VOID
        assert "egm96" in ds.tags()["SIMULATED_REFERENCE_HEIGHTS"]
    assert t.a == pytest.approx(STEP, abs=1e-12) and t.e == pytest.approx(-STEP, abs=1e-12)
    # cell centres on whole multiples of 3″, as SRTM's posts
    for edge in (t.c, t.f):
        centre = edge / STEP + np.sign(t.a if edge == t.c else t.e) * 0.5
        assert centre == pytest.approx(round(centre), abs=1e-6)
    void = data == SRTM_VOID
    assert void.mean() < 0.05                    # 2 % asked (1,020 cells here: one blob or none)
    # against the noise-free cell means written the same way: white noise of 4 m, rounded
    exact = make_geographic_reference(scene / "truth_dem.tif", scene / "exact.tif", geoid,
                                      noise_m=0.0, void_fraction=0.0, seed=0)
    with rasterio.open(exact) as ds:
        assert ds.transform == t
        d = (data.astype(float) - ds.read(1))[~void]
    assert abs(d.mean()) < 0.5 and 3.6 < d.std() < 4.4
    holed = make_geographic_reference(scene / "truth_dem.tif", scene / "holed.tif", geoid,
                                      void_fraction=0.3, seed=0)
    with rasterio.open(holed) as ds:
        assert 0.1 < (ds.read(1) == SRTM_VOID).mean() < 0.4


def test_the_reference_lies_where_the_truth_is(scene, geoid, tmp_path):
    """Noise-free, no voids: the truth averaged onto the reference's cells (GDAL's average,
    through io.reproject) finds no shift against it, and the EGM96 undulation as the height
    difference: each cell is the truth's mean over that cell, orthometric."""
    ref = make_geographic_reference(scene / "truth_dem.tif", tmp_path / "exact.tif", geoid,
                                    noise_m=0.0, void_fraction=0.0)
    c = coregister_dems(ref, scene / "truth_dem.tif", max_shift_m=50.0, resampling="average")
    assert c, c.reason
    r = c.result
    assert np.hypot(r.dx, r.dy) < 0.5, r                 # 0.005 of a 3″ cell
    with rasterio.open(ref) as ds:
        lon, lat = ds.transform @ (ds.width / 2, ds.height / 2)
    n = float(geoid.undulation(np.array([lon]), np.array([lat]), "EPSG:4326")[0])
    assert -r.dz == pytest.approx(n, abs=0.2)            # the truth lies N above the reference
    assert r.nmad_after < 0.5                            # rounding to whole metres


def test_bad_reference_options_are_refused_before_anything_is_written(tmp_path, capsys):
    cases = [["--reference", "geographic", "--reference-geoid", str(tmp_path / "none.gtx")],
             ["--reference-geoid", str(tmp_path / "none.gtx")],
             ["--reference", "projected", "--reference-noise-m", "-1"]]
    for extra in cases:
        out = tmp_path / "sim"
        assert main(["simulate", str(out), "--size", "640", "--quiet", *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert not out.exists()
