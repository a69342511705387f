"""Coarse to fine over the whole a-priori range: image offsets on real
Pléiades texture and on the simulator's texture, 0–120 m per view; heights against heights
against the real SRTM tile; failures are verdicts, never a confident wrong offset."""
import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.core.matching.coarse import (AT_EDGE, LOW_SCORE, OK, dem_offset, image_offset,
                                      search_radius_px)

GSD = 2.5
SIGMA_VIEW_M = 60.0           # a-priori σ of each view's geolocation
RADIUS = search_radius_px(SIGMA_VIEW_M * np.sqrt(2), GSD)     # two views: σ·√2; k = 3


def _pair(texture, dx, dy, rng, side=640, noise=0.02):
    """``reference`` and ``moving`` (side²) with moving(x + dx, y + dy) = reference(x, y),
    cubic resampling, independent noise of ``noise`` × the texture's spread."""
    c = (np.array(texture.shape) - side) // 2
    yy, xx = np.mgrid[0:side, 0:side].astype(float)
    ref = texture[c[0]:c[0] + side, c[1]:c[1] + side].astype(float)
    mov = ndimage.map_coordinates(texture.astype(float), [yy + c[0] - dy, xx + c[1] - dx], order=3)
    s = noise * texture.std()
    return ref + rng.normal(0, s, ref.shape), mov + rng.normal(0, s, ref.shape)


def _sweep(texture, seed, n=8):
    """Each view off by 0–120 m in a random direction; returns errors and formal σ (px)."""
    rng = np.random.default_rng(seed)
    err, sig = [], []
    for _ in range(n):
        e = [rng.uniform(0, 120) * np.array([np.cos(a), np.sin(a)]) for a in rng.uniform(0, 2 * np.pi, 2)]
        dx, dy = (e[1] - e[0]) / GSD
        ref, mov = _pair(texture, dx, dy, rng)
        o = image_offset(ref, mov, RADIUS)
        assert o.status == OK, (dx, dy, o)
        err.append([o.dx - dx, o.dy - dy])
        sig.append([o.sigma_dx, o.sigma_dy])
    return np.array(err), np.array(sig)


@pytest.fixture(scope="module")
def pleiades(shared_data):
    out = []
    for k in (1, 2, 3):
        with rasterio.open(shared_data / "pleiades_triplet" / f"img_0{k}.tif") as ds:
            out.append(ds.read(1).astype(float)[:1000, :1000])
    return out


def test_radius_is_k_sigma_over_gsd():
    assert search_radius_px(50.0, 2.5) == pytest.approx(60.0)
    assert RADIUS == pytest.approx(3 * 60 * np.sqrt(2) / 2.5)
    with pytest.raises(ValueError):
        search_radius_px(10.0, 0.0)


@pytest.mark.parametrize("k", [0, 1, 2])
def test_offsets_up_to_120_m_per_view_on_real_texture(pleiades, k, capsys):
    err, sig = _sweep(pleiades[k], seed=k)
    rms = np.sqrt(np.mean(err ** 2, axis=0))
    with capsys.disabled():
        print(f"\nPléiades {k + 1}: empirical RMS {rms.round(4)} px, formal σ median "
              f"{np.median(sig, axis=0).round(4)} px")
    assert np.abs(err).max() < 0.05
    assert np.all(rms <= np.median(sig, axis=0))      # σ is not optimistic


def test_offsets_on_the_simulators_texture(tmp_path, capsys):
    from prismstation.sim import simulate
    p = simulate(tmp_path, size=800, seed=3, n_gcp=0, n_icp=0, n_tie=0)
    with rasterio.open(p["N"]) as ds:
        n = ds.read(1).astype(float)
    err, sig = _sweep(n, seed=7, n=6)
    rms = np.sqrt(np.mean(err ** 2, axis=0))
    with capsys.disabled():
        print(f"\nsimulator N: empirical RMS {rms.round(4)} px, formal σ median "
              f"{np.median(sig, axis=0).round(4)} px")
    assert np.abs(err).max() < 0.05 and np.all(rms <= np.median(sig, axis=0))


def test_no_confident_wrong_offset(pleiades):
    rng = np.random.default_rng(1)
    # beyond the a-priori range: not "ok"
    ref, mov = _pair(pleiades[0], 150.0, -20.0, rng)
    o = image_offset(ref, mov, 60.0)
    assert o.status != OK
    # unrelated images: not "ok"
    for other in (pleiades[1][::-1, ::-1][:640, :640], rng.normal(0, 1, (640, 640))):
        o = image_offset(pleiades[0][:640, :640], other, RADIUS)
        assert o.status in (LOW_SCORE, AT_EDGE) or not o.ok, o
    # windows too small for the radius: said so
    o = image_offset(pleiades[0][:100, :100], pleiades[0][:100, :100], RADIUS)
    assert o.status == "too_small" and "too small" in o.reason


def test_dem_offset_height_to_height_over_the_whole_radius(shared_data):
    """A 30 m DEM of the real tile's terrain, shifted by up to 120 m (4 cells) with 3 m noise
    and a void, found anywhere within k·σ = 180 m, then refined by surface matching."""
    with rasterio.open(shared_data / "srtm" / "N44E005_UTM.tif") as ds:
        h = ds.read(1).astype(float)[300:420, 300:420]
    h = ndimage.zoom(h, 3, order=3)                      # 90 m → 30 m cells
    t = (30.0, 0.0, 0.0, 0.0, -30.0, 0.0)
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:300, 0:300].astype(float)
    errs = []
    for _ in range(5):
        dE, dN = rng.uniform(-120, 120, 2)
        dcol, drow = dE / 30.0, -dN / 30.0                 # what lays the DEM on the reference
        dem = ndimage.map_coordinates(h, [yy + 30 + drow, xx + 30 + dcol], order=3) + rng.normal(0, 3, yy.shape)
        dem[100:130, 40:90] = np.nan
        ref = h[30:330, 30:330]
        r = dem_offset(ref, dem, t, radius_m=3 * 60.0)
        assert r.converged, r.reason
        errs.append([r.dcol - dcol, r.drow - drow])
        assert abs(r.dcol - dcol) < 3 * r.sigma_dcol + 0.02 and abs(r.drow - drow) < 3 * r.sigma_drow + 0.02
    assert np.abs(errs).max() < 0.1
