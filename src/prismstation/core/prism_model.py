"""The empirical PRISM 1B2 model (Gonçalves 2008) behind the sensor-model seam
(:mod:`prismstation.core.sensor`): each view's ancillary geometry (:mod:`prismstation.core.prism`)
with its fitted bias (:class:`~prismstation.core.prism.BiasFit`); the fit is
:func:`prismstation.core.solve.solve_prism` (bias per view on the GCPs, F−B parallax line)."""
from __future__ import annotations

import numpy as np

from prismstation.core import prism
from prismstation.core.prism import BiasFit
from prismstation.core.sensor import central_partials


class PrismModel:
    """The PRISM model of ``scene`` with ``bias`` (view → :class:`BiasFit`; a view without one
    is uncorrected). Ground ↔ image as :mod:`prismstation.core.prism` computes it:
    ``x = bias(map_to_image(P + relief_shift(P, h)))``."""

    name = "prism"
    bias_models = prism.BIAS_MODELS
    default_bias = "affine"
    parallax_models = prism.PARALLAX_MODELS
    height_source = "parallax"
    holds_view_fixed = False
    description = "ALOS-PRISM 1B2 views"
    workflows = frozenset({"fit", "report", "orient-dem", "dsm"})

    def __init__(self, scene, bias: dict | None = None):
        self.scene = scene
        self.bias = {v: (bias or {}).get(v, BiasFit.identity()) for v in scene.views}

    @classmethod
    def fit(cls, scene, points, settings, *, height_of=None, height_sigma_m=None, revision: int = 0,
            control=None):
        """:func:`prismstation.core.solve.solve_prism` (``height_sigma_m`` is not used: the
        parallax line and the DEM's own height give a point's height)."""
        from prismstation.core.solve import solve_prism
        return solve_prism(scene, points, settings, height_of=height_of, revision=revision,
                           control=control)

    def ground_to_image(self, view: str, en, h) -> np.ndarray:
        v = self.scene.views[view]
        return self.bias[view].apply(prism.ground_to_ancillary(self.scene, v, en, h))

    def image_to_ground(self, view: str, xy, h) -> np.ndarray:
        v = self.scene.views[view]
        return prism.ancillary_to_ground(self.scene, v, self.bias[view].invert(xy), h)

    def partials(self, view: str, en, h) -> tuple[np.ndarray, np.ndarray]:
        """Central differences of :meth:`ground_to_image` (1 m steps): the model is piecewise
        (the ground track's segments), so its analytic derivative is not worth the code."""
        return central_partials(lambda e, hh: self.ground_to_image(view, e, hh), en, h)

    def bias_cov(self, view: str, xy) -> np.ndarray:
        """``(..., 2, 2)`` px²: the bias fit's parameter covariance at image points ``xy``
        ``(..., 2)`` (the bias acts on the ancillary position, ``invert(xy)``)."""
        fit = self.bias[view]
        xy = np.asarray(xy, float)
        if fit.cov is None or fit.cov.size == 0:
            return np.zeros(xy.shape[:-1] + (2, 2))
        J = bias_jacobian(fit, fit.invert(xy))
        return J @ fit.cov @ np.swapaxes(J, -1, -2)

    def fitted(self, view: str) -> bool:
        return self.bias[view].model != "none"

    @property
    def ok(self) -> bool:
        """The reference view's bias is fitted (the other views may step down or stay as they
        are: they only serve predictions)."""
        return self.bias[self.scene.reference_view].model != "none"


def bias_jacobian(fit: BiasFit, xy0) -> np.ndarray:
    """``(..., 2, u)`` derivative of the bias-corrected position at ancillary ``xy0`` ``(..., 2)``
    with respect to the fit's published parameters (``fit.names``)."""
    xy0 = np.asarray(xy0, float)
    x, y = xy0[..., 0], xy0[..., 1]
    one, zero = np.ones_like(x), np.zeros_like(x)
    if fit.model == "shift":
        rows = [[one, zero], [zero, one]]
    elif fit.model == "similarity":   # x += a x − c y + b1 ; y += c x + a y + b2
        rows = [[x, -y, one, zero], [y, x, zero, one]]
    elif fit.model == "affine":       # x += B1 x + B2 y + B5 ; y += B3 x + B4 y + B6
        rows = [[x, y, zero, zero, one, zero], [zero, zero, x, y, zero, one]]
    else:
        return np.zeros(xy0.shape[:-1] + (2, 0))
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)
