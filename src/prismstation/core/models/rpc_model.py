"""The rational function model with an image-space bias behind the sensor-model seam
(:mod:`prismstation.core.models.sensor`; Grodecki & Dial 2003, Fraser & Hanley 2003).

A view is an image with its RPC (:class:`RpcView`); the model works in the scene's map frame
through a :class:`MapProjection` the scene reader supplies (map metres ↔ WGS 84 longitude and
latitude: this layer knows no CRS), so that every caller keeps ground ``(E, N)`` metres and
ellipsoidal ``h`` — the RPC's own heights. The bias of each view
(:class:`~prismstation.core.models.rpc_bias.RpcBias`) is :mod:`prismstation.core.models.rpc_bias`'s,
evaluated at the image point; the fit (:meth:`RpcModel.fit`) is the bias-compensated block
adjustment of :mod:`prismstation.core.models.rpc_solve`, and an orientation from a reference DEM
becomes each view's a-priori bias (:meth:`RpcModel.control_from_record`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from prismstation.core.models import rpc_solve
from prismstation.core.models.recent import Recent
from prismstation.core.models.results import PointColumns
from prismstation.core.models.rpc import Rpc, wrap180
from prismstation.core.models.rpc_bias import BIAS_MODELS, RpcBias, bias_design
from prismstation.core.models.sensor import STEP_M
from prismstation.core.models.solution import Control, Settings, Solution, statistics


class MapProjection(Protocol):
    """Map metres of the scene's CRS ↔ WGS 84 longitude, latitude (degrees); arrays of any
    shape, element by element."""

    def to_lonlat(self, E, N) -> tuple[np.ndarray, np.ndarray]: ...

    def from_lonlat(self, lon, lat) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True, eq=False)
class RpcView:
    """One image with its RPC: ``rpc`` in the image's own pixel frame, ``projection`` the
    scene's map ↔ lon/lat, ``pixel_size_m`` the ground sample distance at the image centre
    (:func:`ground_sample_distance`), ``image`` its file, ``shape`` ``(rows, cols)``."""

    name: str
    rpc: Rpc
    projection: MapProjection
    pixel_size_m: float
    image: str | None = None
    shape: tuple | None = None

    def centre(self) -> tuple[float, float]:
        """The image centre (px), or the RPC's own centre when the shape is unknown."""
        if self.shape:
            return self.shape[1] / 2.0, self.shape[0] / 2.0
        return self.rpc.samp_off + 0.5, self.rpc.line_off + 0.5

    def footprint(self, h: float | None = None) -> np.ndarray:
        """Map ``(E, N)`` ``(4, 2)`` of the image corners at ellipsoidal height ``h`` (default
        the RPC's height offset); NaN where the RPC cannot be inverted."""
        rows, cols = self.shape if self.shape else (2 * (self.rpc.line_off + 0.5), 2 * (self.rpc.samp_off + 0.5))
        px = np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float)
        lon, lat, ok = self.rpc.localize_masked(px[:, 0], px[:, 1], self.rpc.h_off if h is None else h)
        E, N = self.projection.from_lonlat(np.where(ok, lon, 0.0), np.where(ok, lat, 0.0))
        return np.where(ok[:, None], np.column_stack([E, N]), np.nan)


def ground_sample_distance(rpc: Rpc, projection: MapProjection, x: float, y: float,
                           h: float | None = None) -> float:
    """Metres per pixel at image point ``(x, y)``, height ``h`` (default the RPC's offset): the
    square root of the ground area of one pixel."""
    h = rpc.h_off if h is None else h
    lon, lat = rpc.localize(np.array([x]), np.array([y]), h)
    E, N = projection.from_lonlat(lon, lat)
    _, J = _partials_en(rpc.project_with_partials, projection, E, N, np.array([h], float))
    return float(1.0 / np.sqrt(abs(np.linalg.det(J[0, :, :2]))))


def _partials_en(project_with_partials, projection, E, N, h):
    """``(x, y)`` and ∂(x, y)/∂(E, N, h) ``(n, 2, 3)`` px/m of a lon/lat model at map points:
    its analytic partials in degrees chained with the projection's derivative (central
    differences of :data:`~prismstation.core.models.sensor.STEP_M`)."""
    E, N, h = (np.asarray(a, float).reshape(-1) for a in (E, N, h))
    lon, lat = projection.to_lonlat(np.concatenate([E, E + STEP_M, E - STEP_M, E, E]),
                                    np.concatenate([N, N, N, N + STEP_M, N - STEP_M]))
    lon, lat = np.asarray(lon, float).reshape(5, -1), np.asarray(lat, float).reshape(5, -1)
    x, y, Jg = project_with_partials(lon[0], lat[0], h)
    D = np.empty((len(E), 2, 2))                      # ∂(lon, lat)/∂(E, N), degrees per metre
    D[:, 0, 0], D[:, 1, 0] = wrap180(lon[1] - lon[2]) / (2 * STEP_M), (lat[1] - lat[2]) / (2 * STEP_M)
    D[:, 0, 1], D[:, 1, 1] = wrap180(lon[3] - lon[4]) / (2 * STEP_M), (lat[3] - lat[4]) / (2 * STEP_M)
    J = np.concatenate([Jg[:, :, :2] @ D, Jg[:, :, 2:]], axis=2)
    return np.column_stack([x, y]), J


class RpcModel:
    """The RPC model of ``scene`` (views :class:`RpcView`) with ``bias`` (view →
    :class:`RpcBias`; a view without one is unbiased). What held the fit: ``undetermined`` view →
    the names of the parameters the data left at their a-priori σ
    (:func:`~prismstation.core.models.rpc_solve.undetermined`), ``gcps`` the GCPs and
    ``held`` the tie points held to the reference DEM's heights in the adjustment."""

    name = "rpc"
    bias_models = BIAS_MODELS
    default_bias = "shift"
    parallax_models = ()
    height_source = "intersection"
    holds_view_fixed = True
    description = "images with RPCs"
    workflows = frozenset({"fit", "report", "orient-dem", "dsm"})

    def __init__(self, scene, bias: dict | None = None, *, undetermined: dict | None = None, gcps: int = 0,
                 held: int = 0):
        self.scene = scene
        self.undetermined = dict(undetermined or {})
        self.gcps, self.held = int(gcps), int(held)
        self.bias = {v: (bias or {}).get(v) or RpcBias() for v in scene.views}
        self.models = {v: self.bias[v].biased(view.rpc) for v, view in scene.views.items()}

    @classmethod
    def fit(cls, scene, points, settings: Settings = Settings(), *, height_of=None,
            height_sigma_m: float | None = None, revision: int = 0, control: Control | None = None,
            recent: Recent | None = None) -> Solution:
        """Every view's bias by the block adjustment of GCPs and tie points
        (:func:`prismstation.core.models.rpc_solve.fit_block`: ``height_of`` and ``height_sigma_m``
        hold tie points to the reference DEM where the GCPs are too few; ``control`` gives each
        view's a-priori bias), then every point through the fitted model: intersected from its
        rays, or where its one ray meets ``height_of``, else at the mean height (``recent`` is
        not used: the adjustment takes every point at once)."""
        fit = rpc_solve.fit_block(scene, points, settings, height_of=height_of, height_sigma_m=height_sigma_m,
                                  control=control)
        model = cls(scene, fit.bias, undetermined=fit.undetermined, gcps=len(fit.block.gcps), held=fit.held)
        results, mean_h = fit.block.evaluate(model, fit.result, height_of, settings)
        columns = PointColumns.of(results, scene.views)
        return Solution(scene, settings, model, columns, statistics(scene, columns), tuple(fit.messages), mean_h,
                        revision, fit.failures, tuple(fit.block.points))

    @staticmethod
    def control_from_record(scene, record: dict) -> Control:
        """Each view's a-priori bias from a project's saved ``dem_control`` record
        (:func:`prismstation.core.models.rpc_solve.control_from_record`)."""
        return rpc_solve.control_from_record(scene, record)

    def ground_to_image(self, view: str, en, h) -> np.ndarray:
        en = np.asarray(en, float)
        lon, lat = self.scene.views[view].projection.to_lonlat(en[..., 0], en[..., 1])
        x, y = self.models[view].project(np.asarray(lon, float), np.asarray(lat, float), h)
        return np.stack([x, y], axis=-1)

    def image_to_ground(self, view: str, xy, h) -> np.ndarray:
        """Map ``(E, N)`` of image ``xy`` at height ``h``; NaN where Newton does not converge
        (far outside the RPC's domain)."""
        xy = np.asarray(xy, float)
        m = self.models[view]
        d = m.bias_at(xy[..., 0], xy[..., 1])
        lon, lat, ok = m.rpc.localize_masked(xy[..., 0] - d[..., 0], xy[..., 1] - d[..., 1], h)
        E, N = self.scene.views[view].projection.from_lonlat(np.where(ok, lon, 0.0), np.where(ok, lat, 0.0))
        out = np.stack([np.asarray(E, float), np.asarray(N, float)], axis=-1)
        return np.where(ok[..., None], out, np.nan)

    def partials(self, view: str, en, h) -> tuple[np.ndarray, np.ndarray]:
        """Analytic partials of the biased RPC chained with the map projection's derivative."""
        en = np.asarray(en, float).reshape(-1, 2)
        h = np.broadcast_to(np.asarray(h, float), (len(en),))
        return _partials_en(self.models[view].project_with_partials, self.scene.views[view].projection,
                            en[:, 0], en[:, 1], h)

    def bias_cov(self, view: str, xy) -> np.ndarray:
        """``(..., 2, 2)`` px²: ``(I − ∂Δ/∂xy)⁻¹ D cov Dᵀ (…)ᵀ`` with ``D`` the bias's design at
        ``xy`` (the biased model solves ``xy = rpc + Δ(xy)``)."""
        b = self.bias[view]
        xy = np.asarray(xy, float)
        if b.cov.size == 0:
            return np.zeros(xy.shape[:-1] + (2, 2))
        D = bias_design(b.model, xy[..., 0], xy[..., 1], b.x0, b.y0)
        A = np.linalg.inv(np.eye(2) - b.M)
        AD = A @ D
        return AD @ b.cov @ np.swapaxes(AD, -1, -2)

    def fitted(self, view: str) -> bool:
        """The view's bias was fitted, or it is the datum."""
        b = self.bias[view]
        return b.fixed or b.model != "none"

    @property
    def ok(self) -> bool:
        """An RPC is a model before any fit: a failed fit is the solution's ``failures``."""
        return True

    @property
    def heights_fitted(self) -> bool:
        """Points seen in two images or more are intersected: their heights are the model's."""
        return True

    def adjustments(self) -> tuple:
        """``((label, LsqResult), ...)``: the block adjustment (its reference view's share),
        whose residuals are tested for blunders."""
        ref = self.scene.reference_view
        lsq = self.bias[ref].lsq
        return () if lsq is None else ((f"{ref} bias", lsq),)

    def describe(self) -> dict:
        """The model's own part of a report's ``model`` section: nothing beyond the biases."""
        return {}
