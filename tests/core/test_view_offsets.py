"""Each view's offset from N over the whole a-priori range, on a simulated triplet whose views
are off by up to ~100 m each (rendered once, then its geolocation perturbed): recovered to a
fraction of a pixel across track; along track within the parallax that the reference DEM's
height errors leave (Δh·tanθ)."""
import json

import numpy as np
import pytest
import rasterio
from scipy import ndimage

from prismstation.core.orientation import view_offsets as vo
from prismstation.io.scene import read_scene
from prismstation.sim import simulate
from prismstation.sim.perturb import perturb_geolocation
from prismstation.sim.reference import make_reference_dem

SIZE = 1600
SIGMA_M = 60.0          # a-priori σ per view and component: radius 3·60·√2 / 2.5 = 102 px


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("vo")
    simulate(d, size=SIZE, seed=2, n_gcp=0, n_icp=3, n_tie=0,
             geolocation_errors={"N": (60.0, -40.0), "F": (-80.0, 70.0), "B": (30.0, 95.0)})
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=1)
    return d


def _sampler(path, geoid=55.0):
    with rasterio.open(path) as ds:
        h = ds.read(1).astype(float)
        h[h == ds.nodata] = np.nan
        t = ds.transform
    filled = np.where(np.isfinite(h), h, np.nanmean(h)) + geoid

    def sample(e, n):
        c, r = ~t * (e, n)
        return ndimage.map_coordinates(filled, [r - 0.5, c - 0.5], order=1, mode="nearest")
    return sample


def _offsets(d, scene_file):
    scene = read_scene(scene_file)
    sample = _sampler(d / "srtm.tif")
    img = {}
    for v in "NFB":
        with rasterio.open(d / f"{v}.tif") as ds:
            img[v] = ds.read(1).astype(np.float32)
    radius = vo.search_radius_px(SIGMA_M * np.sqrt(2), 2.5)
    out = {"F": [], "B": []}
    wins = vo.lattice((SIZE, SIZE), 480, k=2, margin_px=160)
    for win in (wins[0], wins[3]):
        c0, r0, w, h = win
        hh = vo.n_heights(scene, win, sample, 600.0)
        for v in "FB":
            a0, b0, aw, ah = vo.source_window(scene, v, win, hh, radius + 12)
            sub = np.full((ah, aw), np.nan, np.float32)
            ra0, ca0, ra1, ca1 = max(b0, 0), max(a0, 0), min(b0 + ah, SIZE), min(a0 + aw, SIZE)
            sub[ra0 - b0:ra1 - b0, ca0 - a0:ca1 - a0] = img[v][ra0:ra1, ca0:ca1]
            out[v].append(vo.view_offset(scene, v, img["N"][r0:r0 + h, c0:c0 + w], win, sub,
                                         (a0, b0), hh, SIGMA_M))
    return scene, out


def _expected(scene, errors_en):
    """N-space pixels of (view error − N error): J_N·(e_v − e_N)."""
    j = scene.views["N"].map_to_image.linear
    return {v: j @ (errors_en[v] - errors_en["N"]) for v in "FB"}


def _check(scene, offs, errors_en, capsys):
    exp = _expected(scene, errors_en)
    for v in "FB":
        assert np.hypot(*exp[v]) > 40                      # the old ±12 px search could not
        for o in offs[v]:
            assert o.ok, o
            with capsys.disabled():
                print(f"\n{v}: found ({o.dx:+.2f}, {o.dy:+.2f}) ± ({o.sigma_dx:.3f}, {o.sigma_dy:.3f}) px, true "
                      f"({exp[v][0]:+.2f}, {exp[v][1]:+.2f})")
            assert abs(o.dx - exp[v][0]) < 0.5            # across track (1B2-R x)
            assert abs(o.dy - exp[v][1]) < 4.0            # along track: Δh·tanθ of the reference
            # the σ claims it: within 2.5σ on each axis, the along-track σ of a few px
            assert abs(o.dx - exp[v][0]) < 2.5 * o.sigma_dx + 0.1
            assert abs(o.dy - exp[v][1]) < 2.5 * o.sigma_dy and o.sigma_dy < 3.0
        mean, sig, verdict = vo.combine(offs[v] * 2)       # ≥ 3 windows for a verdict
        assert verdict is not None and np.all(np.isfinite(sig))


def test_offsets_of_the_rendered_scene(scene_dir, capsys):
    scene, offs = _offsets(scene_dir, scene_dir / "scene.json")
    truth = json.loads((scene_dir / "truth.json").read_text())
    e = {v: np.array([truth["views"][v]["geolocation_error_m"][k] for k in ("E", "N")]) for v in "NFB"}
    _check(scene, offs, e, capsys)


def test_offsets_after_perturbing_the_published_geolocation(scene_dir, capsys):
    errors = {"N": (-100.0, 0.0), "F": (0.0, 100.0), "B": (70.7, -70.7)}
    path = perturb_geolocation(scene_dir, errors, scene_dir / "perturbed" / "scene.json")
    scene, offs = _offsets(scene_dir, path)
    from prismstation.sim.perturb import truth_geometry
    truth = json.loads((scene_dir / "truth.json").read_text())
    orbit, _, _ = truth_geometry(truth)
    e = {v: errors[v][0] * orbit.t + errors[v][1] * orbit.a for v in "NFB"}
    _check(scene, offs, e, capsys)


def test_combine_flags_a_window_that_disagrees():
    """Windows agreeing within their σ and the field allowance combine to their weighted mean,
    verdict ok; one window 8 px off (a false peak) makes the verdict inconsistent and widens σ."""
    rng = np.random.default_rng(0)
    wins = vo.lattice((4000, 4000), 512, k=3)

    def make(shift_of_5=0.0):
        return [vo.ViewOffset("F", w, 40 + rng.normal(0, 0.1) + (shift_of_5 if i == 5 else 0.0),
                              -56 + rng.normal(0, 1.0), 0.05, 2.0, 100.0, "ok", "", 0.9)
                for i, w in enumerate(wins)]
    mean, sig, verdict = vo.combine(make())
    assert verdict.ok and abs(mean[0] - 40) < 0.2 and abs(mean[1] + 56) < 1.0
    mean2, sig2, verdict2 = vo.combine(make(8.0))
    assert verdict2.status == "inconsistent" and verdict2.worst == 5 and sig2[0] > 2 * sig[0]
    failed = make() + [vo.ViewOffset("F", wins[0], np.nan, np.nan, np.nan, np.nan, 100.0,
                                     "low_score", "NCC 0.1", 0.1)]
    assert np.allclose(vo.combine(failed)[0], vo.combine(failed[:-1])[0])


def test_gradient_recovers_a_drifting_offset():
    """Attitude drift makes a view's offset vary over N: the windows' offsets give it as an
    affine field about N's centre; too few windows, or windows on a line, give a constant."""
    rng = np.random.default_rng(3)
    centre = np.array([7000.0, 7000.0])
    o, G = np.array([1.2, -0.4]), np.array([[2e-5, -1e-5], [3e-5, -2.1e-4]])   # −1.5…+1.5 px along y
    wins = vo.lattice((14000, 14000), 512, k=3, margin_px=100)

    def win(w):
        p = np.array([w[0] + w[2] / 2, w[1] + w[3] / 2])
        d = o + G @ (p - centre) + rng.normal(0, 0.05, 2)
        return vo.ViewOffset("F", w, d[0], d[1], 0.05, 0.05, 100.0, "ok", "", 0.9)
    found = [win(w) for w in wins]
    o_hat, G_hat = vo.gradient(found, centre)
    assert np.abs(o_hat - o).max() < 0.08 and np.abs(G_hat - G).max() < 1.5e-5
    at = vo.offset_at(o_hat, G_hat, centre, np.array([[100.0, 13900.0], [7000.0, 7000.0]]))
    assert at[1] == pytest.approx(o_hat) and at[0] == pytest.approx(o + G @ ([100, 13900] - centre), abs=0.2)
    few = found[:3]
    o3, G3 = vo.gradient(few, centre)
    assert not G3.any() and o3 == pytest.approx(np.mean([[f.dx, f.dy] for f in few], axis=0))
    line = [f for f in found if f.n_window[1] == wins[0][1]] + [found[0]]   # one row of windows
    assert not vo.gradient(line, centre)[1].any()
    assert np.isnan(vo.gradient([], centre)[0]).all()
    # windows that scatter by ±2 px around a constant (the reference's height errors where N's
    # 100 m error samples it on slopes) give no gradient to carry over the scene
    rng2 = np.random.default_rng(11)
    noisy = [vo.ViewOffset("F", w, -7.4 + rng2.normal(0, 0.05), -12 + rng2.normal(0, 2.5), 0.05, 2.0,
                           100.0, "ok", "", 0.9) for w in wins]
    o_n, G_n = vo.gradient(noisy, centre)
    assert not G_n.any() and o_n == pytest.approx(np.mean([[f.dx, f.dy] for f in noisy], axis=0))


def _draw_n_error(rng, keys_f, keys_b, sigma_m, par, w, n, common_m=0.0, field=0.0):
    """``n`` draws of ``(1 − w)·δF + w·δB`` (px along track): each window's height error δh_i
    (par ∝ it: F's offset +par·δh, B's −par·δh, σ_h = 1), a common one, each window's matching
    noise ``sigma_m`` and field deviation ``field``; each view's offset the weighted mean of its
    windows, weighted as ``combine`` weighs them (equal σ here: equally)."""
    keys = sorted(set(keys_f) | set(keys_b))
    dh = rng.normal(0, 1, (n, len(keys))) + rng.normal(0, common_m, (n, 1))
    out = np.zeros(n)
    for v, ks, sign, wv in (("F", keys_f, +1, 1 - w), ("B", keys_b, -1, w)):
        idx = [keys.index(k) for k in ks]
        e = sign * par[v] * dh[:, idx] + rng.normal(0, np.hypot(sigma_m, field), (n, len(idx)))
        out += wv * e.mean(axis=1)
    return out


@pytest.mark.parametrize("shared", [9, 6, 3, 0])
def test_n_position_sigma_counts_the_height_error_only_where_f_and_b_windows_differ(shared):
    rng = np.random.default_rng(shared)
    tan_f, tan_b, gsd, sigma_h = 0.44, 0.40, 2.5, 10.0
    w = tan_f / (tan_f + tan_b)
    par = {"F": sigma_h * tan_f / gsd, "B": sigma_h * tan_b / gsd}       # px per σ_h
    keys = [(i, 0) for i in range(18)]
    keys_f = keys[:9]
    keys_b = keys[9 - shared:18 - shared]                                # `shared` of them in both
    sigma_m, along = 0.3, (0.0, 1.0)
    windows = {"F": {k: (0.05, float(np.hypot(sigma_m, par["F"]))) for k in keys_f},
               "B": {k: (0.05, float(np.hypot(sigma_m, par["B"]))) for k in keys_b}}
    s = vo.n_along_sigma_px(windows, par, along, w, sigma_field_px=0.0)
    # the reference error common to every window cancels whole: drawn 30 m here
    draws = _draw_n_error(rng, keys_f, keys_b, sigma_m, par,
                          w, 40000, common_m=3.0)
    assert s == pytest.approx(np.std(draws), rel=0.03)
    if shared == 9:   # the same windows: the heights' error cancels, the matching's is left
        assert s == pytest.approx(np.hypot((1 - w) * sigma_m, w * sigma_m) / 3, rel=1e-9)
    if shared == 0:   # disjoint windows: nothing cancels between them
        k = (1 - w) * par["F"]
        assert s == pytest.approx(np.hypot(np.hypot((1 - w) * sigma_m, w * sigma_m) / 3, k * np.sqrt(2 / 9)), rel=1e-9)


def test_n_position_sigma_without_the_windows_of_a_view_is_not_a_number():
    assert np.isnan(vo.n_along_sigma_px({"F": {(0, 0): (0.1, 2.0)}, "B": {}}, {"F": 1.8, "B": 1.8},
                                        (0.0, 1.0), 0.5))
