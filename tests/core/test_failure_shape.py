"""One failure shape for results (core/adjustment/estimate.py, "Failure as a value"): falsy when it
failed, with a reason; truthy with an empty reason when it did not."""
import math

import numpy as np

from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.matching.coreg import CoregResult
from prismstation.core.matching.dense import ParallaxMap
from prismstation.core.models.ray_dem import ray_meets_surface
from prismstation.core.models.resection import FrameCamera, project, resect


def _check(ok, failed):
    assert ok and not getattr(ok, "reason", "")
    assert not failed and isinstance(failed.reason, str) and failed.reason


def test_every_result_that_can_fail_is_falsy_with_a_reason():
    src = np.array([[0, 0], [10, 0], [0, 10], [10, 10]], float)
    _check(Affine2D.fit(src, src * 2 + 1), Affine2D.fit(src[:2], src[:2]))

    nums = dict(dcol=0.0, drow=0.0, dx=0.0, dy=0.0, dz=0.0, sigma_dcol=0.1, sigma_drow=0.1, sigma_dx=1.0,
                sigma_dy=1.0, sigma_dz=0.1, iterations=3, count=500, nmad_before=2.0, nmad_after=1.0,
                mean_after=0.0, std_after=1.0)
    _check(CoregResult(**nums, converged=True), CoregResult(**nums, converged=False, reason="too flat"))

    a = np.zeros((4, 4), np.float32)
    _check(ParallaxMap(a, a, (0, 0, 4, 4), False), ParallaxMap(a, a, (0, 0, 4, 4), True))

    ray = lambda h: np.column_stack([np.zeros_like(h), np.zeros_like(h)])    # noqa: E731
    _check(ray_meets_surface(ray, lambda en: np.full(len(en), 100.0), 0.0),
           ray_meets_surface(ray, lambda en: np.full(len(en), np.nan), 0.0))

    rng = np.random.default_rng(0)
    cam = FrameCamera(0.153, 10e-6, 5000.0, 4000.0)
    eo = np.array([1000.0, 2000.0, 1800.0, math.radians(2), math.radians(-3), math.radians(30)])
    xyz = np.column_stack([rng.uniform(300, 1800, 30), rng.uniform(1300, 2800, 30), rng.uniform(0, 200, 30)])
    xy = project(cam, eo, xyz) + rng.normal(0, 0.5, (30, 2))
    _check(resect(cam, xy, xyz), resect(cam, xy, xyz, max_iterations=1))
