"""ops.coarse_offsets from files: a simulated triplet whose views are off by 100 m each in
independent directions, an SRTM-like reference; F and B found relative to N over the a-priori
range, with a verdict, and a JSON-safe record."""
import json

import numpy as np

from prismstation.io.scene import read_scene
from prismstation.ops.coarse_offsets import coarse_view_offsets
from prismstation.sim import simulate
from prismstation.sim.reference import make_reference_dem


def test_coarse_offsets_of_a_triplet_off_by_100_m_per_view(tmp_path, capsys):
    d = tmp_path
    errors = {"N": (0.0, -100.0), "F": (100.0, 0.0), "B": (-70.7, 70.7)}
    simulate(d, size=1600, seed=4, n_gcp=0, n_icp=3, n_tie=0, geolocation_errors=errors)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=2)
    scene = read_scene(d / "scene.json")
    seen = []
    res = coarse_view_offsets(scene, d / "srtm.tif", 55.0, sigma_apriori_m=60.0, grid=2,
                              progress=lambda f, m="": seen.append(f))
    assert seen[-1] == 1.0
    truth = json.loads((d / "truth.json").read_text())
    e = {v: np.array([truth["views"][v]["geolocation_error_m"][k] for k in ("E", "N")]) for v in "NFB"}
    j = scene.views["N"].map_to_image.linear
    for v in "FB":
        exp = j @ (e[v] - e["N"])
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
