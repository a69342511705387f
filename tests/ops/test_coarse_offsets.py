"""ops.coarse_offsets from files: a simulated triplet whose views are off by 100 m each in
independent directions, an SRTM-like reference; F and B found relative to N over the a-priori
range, with a verdict, and a JSON-safe record."""
import json

import numpy as np
import pytest

from prismstation.core.orientation import view_offsets

from prismstation.io.scene import read_scene
from prismstation.ops.coarse_offsets import coarse_view_offsets
from prismstation.sim import simulate
from prismstation.sim.reference import make_reference_dem


@pytest.fixture(scope="module")
def triplet(tmp_path_factory):
    d = tmp_path_factory.mktemp("off100")
    errors = {"N": (0.0, -100.0), "F": (100.0, 0.0), "B": (-70.7, 70.7)}
    simulate(d, size=1600, seed=4, n_gcp=0, n_icp=3, n_tie=0, geolocation_errors=errors)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=2)
    return d


def _truth(d, scene):
    """The true N-space offsets of F and B from N (px) and N's own error (m, E, N)."""
    truth = json.loads((d / "truth.json").read_text())
    e = {v: np.array([truth["views"][v]["geolocation_error_m"][k] for k in ("E", "N")]) for v in "NFB"}
    j = scene.views["N"].map_to_image.linear
    return {v: j @ (e[v] - e["N"]) for v in "FB"}, e["N"]


def test_coarse_offsets_of_a_triplet_off_by_100_m_per_view(triplet, capsys):
    d = triplet
    scene = read_scene(d / "scene.json")
    seen = []
    res = coarse_view_offsets(scene, d / "srtm.tif", 55.0, sigma_apriori_m=60.0, grid=2,
                              progress=lambda f, m="": seen.append(f))
    assert seen[-1] == 1.0
    truths, _ = _truth(d, scene)
    for v in "FB":
        exp = truths[v]
        got, sig = res.offsets_px[v], res.sigma_px[v]
        with capsys.disabled():
            print(f"\n{v}: {got.round(2)} ± {sig.round(2)} px, true {exp.round(2)}; "
                  f"{res.verdicts[v].message if res.verdicts[v] else None}; "
                  f"{[(w.status, w.reason) for w in res.windows if w.view == v]}")
        assert np.hypot(*exp) > 50 and res.ok(v)
        assert abs(got[0] - exp[0]) < 0.5 and abs(got[1] - exp[1]) < 3.0
        assert np.all(np.abs(got - exp) < 2.5 * sig + [0.1, 0.0])        # the σ are claims
        assert sum(w.ok for w in res.windows if w.view == v) == 4, [(w.status, w.reason) for w in res.windows]
    json.dumps(res.to_dict(), allow_nan=False)


def test_windows_agree_once_n_is_placed_and_the_view_rewarped(triplet, monkeypatch):
    """Two sources of pixel-size scatter in the windows on this hilly scene, both removed: the
    reference heights sampled where N's 100 m error puts its pixels (``n_shift``: N's error as
    the DEM orientation's first pass knows it), and the relief taken where the view's own error
    puts its pixels (the re-warp with the offset found)."""
    d = triplet
    scene = read_scene(d / "scene.json")
    exp, e_n = _truth(d, scene)
    placed = lambda xy: np.broadcast_to(-e_n, xy.shape)  # noqa: E731  (true = ancillary − error)

    def errors(**kw):
        res = coarse_view_offsets(scene, d / "srtm.tif", 55.0, sigma_apriori_m=60.0, grid=2, **kw)
        return np.array([[w.dx - exp[w.view][0], w.dy - exp[w.view][1]] for w in res.windows if w.ok])

    both = errors(n_shift=placed)
    assert len(both) == 8 and np.abs(both).max() < 0.5, both
    assert np.abs(errors()).max() > 2.0                       # without the placement
    monkeypatch.setattr(view_offsets, "REWARPS", 0)
    assert np.abs(errors(n_shift=placed)).max() > 2.0         # without the re-warp
