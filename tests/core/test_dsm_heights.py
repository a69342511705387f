"""Which heights a DSM follows (core.surfaces.dsm_heights): the parallax line or the rays through the
biases, chosen by the GCPs left out in turn."""
import dataclasses

import numpy as np
import pytest

from prismstation.core.surfaces.dsm_heights import choose_heights, loo_height_errors, model_height_correction
from prismstation.core.models.prism import FixedPrism
from prismstation.core.models.solution import Control, solve

from prismstation.sim.model_triplet import make_points, make_scene


def _drifting(points, size, drift_px):
    """The F view's along-track coordinate drifts linearly over the image rows by up to
    ``drift_px`` (attitude drift): F's bias affine absorbs it, the parallax line cannot."""
    out = []
    for p in points:
        x, y = p.image["F"]
        out.append(dataclasses.replace(p, image={**p.image, "F": (x, y + drift_px * y / size)}))
    return out


def test_a_drift_the_line_cannot_follow_chooses_the_rays():
    sc = make_scene(size=14000)
    pts = _drifting(make_points(sc, n_gcp=9, n_icp=20, noise_px=0.0, seed=3), 14000, 3.0)
    sol = solve(sc, pts)
    line, rays = loo_height_errors(sol)
    assert len(line) == len(rays) == 9
    assert np.sqrt(np.mean(rays ** 2)) < 0.05          # exact data: the rays predict every GCP
    assert np.sqrt(np.mean(line ** 2)) > 1.0           # 3 px of drift is metres of height
    c = choose_heights(sol)
    assert c.model == "rays" and c.n == 9 and c.loo_rms_m["rays"] < c.loo_rms_m["line"]
    assert "leave-one-out over 9 GCPs" in c.reason


def test_the_left_out_error_is_a_refit_without_the_point():
    sc = make_scene(size=6000)
    pts = make_points(sc, n_gcp=8, n_icp=5, noise_px=0.4, seed=1)
    line, rays = loo_height_errors(solve(sc, pts))
    k = 2   # the third GCP, left out by hand
    fit = solve(sc, pts[:k] + [dataclasses.replace(pts[k], kind="ICP")] + pts[k + 1:])
    e, n, h = fit.point(pts[k].id).ground_est
    corr = model_height_correction(fit, h - 100, h + 100)
    assert line[k] == pytest.approx(h - pts[k].ground[2], abs=1e-9)
    assert rays[k] == pytest.approx(h - float(corr(np.array([e, n]), h)) - pts[k].ground[2], abs=1e-9)
    assert abs(line[k] - rays[k]) > 1e-4                # noisy data: the two models differ


def test_too_few_gcps_keep_the_line_and_say_why():
    sc = make_scene(size=6000)
    c = choose_heights(solve(sc, make_points(sc, n_gcp=4, n_icp=5, noise_px=0.3, seed=2)))
    assert c.model == "line" and c.loo_rms_m == {} and "fewer than 5" in c.reason


def test_an_orientation_without_gcps_keeps_its_line():
    sc = make_scene(size=6000)
    sol = solve(sc, make_points(sc, n_gcp=9, n_icp=5, seed=4))
    dem = solve(sc, make_points(sc, n_gcp=0, n_icp=5, seed=4),
                control=Control("a reference DEM", FixedPrism(sol.bias, sol.model.parallax), sol.mean_height))
    assert choose_heights(dem).model == "line" and not dem.observations


def test_asked_for_models_and_unknown_names():
    sc = make_scene(size=6000)
    sol = solve(sc, make_points(sc, n_gcp=9, n_icp=5, seed=5))
    assert choose_heights(sol, "rays").model == "rays" and choose_heights(sol, "line").model == "line"
    with pytest.raises(ValueError, match="unknown height model"):
        choose_heights(sol, "plane")
