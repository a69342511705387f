"""Point transfer takes its search range from the model's geolocation σ:
wide with the ancillary model, narrow once the biases are fitted."""
import json

import numpy as np
import pytest

from prismstation.core.orientation.dem_orient import identity_control
from prismstation.core.models.solution import solve
from prismstation.io.scene import read_scene
from prismstation.io.windows import ImageWindows
from prismstation.ops.coarse_offsets import SIGMA_APRIORI_M
from prismstation.ops.transfer import transfer
from prismstation.ops.transfer_rays import FITTED_SIGMA_M, model_sigma_m
from prismstation.sim import simulate


@pytest.mark.slow  # ~20 s
def test_transfer_with_the_ancillary_model_finds_views_off_by_60_m(tmp_path):
    # each view off by 60 m in its own direction: F and B up to 120 m (48 px) from N's prediction
    errors = {"N": (60.0, 0.0), "F": (-42.4, 42.4), "B": (0.0, -60.0)}
    simulate(tmp_path, size=1200, seed=3, geolocation_errors=errors)
    scene = read_scene(tmp_path / "scene.json")
    truth = json.loads((tmp_path / "truth.json").read_text())["points"]
    h0 = float(np.mean([p["h"] for p in truth]))
    sol = solve(scene, [], control=identity_control(scene, h0))
    assert model_sigma_m(sol) == SIGMA_APRIORI_M
    found, errs, blunders = 0, [], 0
    with ImageWindows(scene) as im:
        for p in truth[:30]:
            tr = transfer(sol, im, "N", p["image"]["N"])
            for v in "FB":
                if tr[v].ok:
                    e = np.hypot(tr[v].x - p["image"][v][0], tr[v].y - p["image"][v][1])
                    found += 1
                    blunders += e > 2.0
                    errs.append(e)
                    # the prediction itself is tens of pixels off: the wide search found it
                    assert np.hypot(*np.subtract(tr[v].predicted, p["image"][v])) > 10
    assert found >= 0.8 * 60 and blunders == 0 and np.median(errs) < 0.5, (found, blunders, errs)


def test_fitted_model_searches_narrow():
    from dataclasses import replace

    from prismstation.core.models.prism import BiasFit
    from prismstation.core.models.prism_model import PrismModel
    from prismstation.sim.model_triplet import make_scene
    sc = make_scene()
    sol = solve(sc, [], control=identity_control(sc, 500.0))
    xy0 = np.random.default_rng(0).uniform(0, 1e4, (8, 2))
    fitted = replace(sol, model=PrismModel(sc, {v: BiasFit.fit(xy0, xy0 + 3.0, "shift") for v in sc.views},
                                         sol.model.parallax))
    assert model_sigma_m(sol) == SIGMA_APRIORI_M and model_sigma_m(fitted) == FITTED_SIGMA_M
