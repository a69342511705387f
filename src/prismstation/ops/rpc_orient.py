"""Orientation of images with RPCs from a reference DEM: the relative DSM laid on the reference.

The DSM of the images as they are oriented (raw RPCs, or biases fitted with one image held
fixed: the block sits where that image's RPC puts it) is co-registered to the reference DEM
(:func:`prismstation.core.matching.coarse.dem_offset`: an exhaustive search over the a-priori radius,
then least-squares surface matching, Gruen & Akca 2005) on a grid of the reference's own cell
size. The result is a ground translation ``s = (dE, dN, dU)``: the DSM's point ``X`` truly lies
at ``X + s``. An image point ``xy`` the DSM put at ``X`` (``xy = rpc(X) + Δ(xy)``) must then be
``rpc(X + s) + Δ'(xy)``, so each image's new bias is fitted (least squares, the bias model's own
design) to ``Δ'(xy) = Δ(xy) + rpc(X) − rpc(X + s)`` over the DSM's cells. The relative biases
between the images are kept; the block's datum becomes the reference's. Each bias's σ is the
translation's σ carried through the same fit.

A-priori: the RPCs' absolute error, which bounds the search (``max_shift_m``; default
:data:`DEFAULT_MAX_SHIFT_M`, beyond the 10–35 m CE90 of Pléiades, SPOT 6/7 and WorldView
products without GCPs). Heights: the DSM's are ellipsoidal; a reference with orthometric
heights (SRTM, Copernicus DEM) needs its geoid (``geoid``, as :func:`prismstation.io.dem.read_dem`
takes it), or its undulation lands in the vertical shift and so in the biases.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core.matching.coarse import dem_offset
from prismstation.core.matching.coreg import CoregResult, block_mean
from prismstation.core.models.rpc_bias import BIAS_MODELS, BiasedRpc, as_biased, bias_design, metres_per_degree
from prismstation.errors import InputError
from prismstation.io.dem import read_dem
from prismstation.io.rpc_scene import to_lonlat
from prismstation.ops.rpc_dsm import rpc_dsm

#: default bound of the horizontal shift (metres)
DEFAULT_MAX_SHIFT_M = 100.0
#: fewest co-registration cells with both heights
MIN_CELLS = 50
#: fewest co-registration cells along each side of the DSM
MIN_SIDE_CELLS = 4


@dataclass(frozen=True, eq=False)
class RpcDemOrientation:
    """Each image's model with the reference's datum (``models``, :class:`BiasedRpc`), the
    bias each gained (``bias_change`` (p,) px) with its σ (``bias_sigma``), the ground
    translation ``shift_m`` (dE, dN, dU) and ``sigma_m``, the co-registration (``coreg``,
    falsy with a reason when it failed: then ``models`` are the input's) and its grid's
    cell size ``cell_m``."""

    models: list
    bias_change: list
    bias_sigma: list
    shift_m: tuple
    sigma_m: tuple
    coreg: CoregResult
    cell_m: float

    def __bool__(self) -> bool:
        return bool(self.coreg)


def coregistration_grid(dsm_transform, dsm_shape, reference_cell_m: float):
    """The DSM's grid coarsened by an integer factor to about the reference's cell size:
    ``(factor, transform, shape)``."""
    a = float(dsm_transform[0])
    f = max(1, int(round(reference_cell_m / a)))
    t = (a * f, 0.0, float(dsm_transform[2]), 0.0, float(dsm_transform[4]) * f, float(dsm_transform[5]))
    return f, t, (dsm_shape[0] // f, dsm_shape[1] // f)


def orient_from_reference(models, dsm_heights, dsm_transform, dsm_crs, reference, *, bias: str = "shift",
                          geoid=None, max_shift_m: float = DEFAULT_MAX_SHIFT_M,
                          cell_m: float | None = None) -> RpcDemOrientation:
    """Biases laying the images' DSM on the reference DEM file ``reference``.

    ``models`` the images' :class:`Rpc` / :class:`BiasedRpc` that made the DSM;
    ``dsm_heights`` (rows, cols) ellipsoidal metres (NaN void) on the north-up grid
    ``dsm_transform`` of the projected ``dsm_crs``; ``bias`` the model of the output biases
    (an image whose input bias is richer keeps its own); ``geoid`` for an orthometric
    reference (module docstring); ``cell_m`` the co-registration cell (default the
    reference's own). A failed co-registration returns the input models and a falsy result.
    """
    if bias not in BIAS_MODELS or bias == "none":
        raise InputError(f"bias model {bias!r}: choose shift, shift_drift or affine")
    ref_full = read_dem(reference, what="reference DEM")
    if cell_m is None:
        cell_m = float(min(ref_full.source_cell_m))
    f, t, shape = coregistration_grid(dsm_transform, np.shape(dsm_heights), cell_m)
    models = [as_biased(m) for m in models]
    if min(shape) < MIN_SIDE_CELLS:
        return _failed(models, t, f"the images' DSM covers {shape[0]} × {shape[1]} cells of {t[0]:g} m, too few "
                       f"for the surface matching ({MIN_SIDE_CELLS} each way at least); the reference still gives "
                       "the heights through the tie points: fit --dem REFERENCE holds them to it")
    dem = block_mean(np.asarray(dsm_heights, float), f)[:shape[0], :shape[1]]
    ref = read_dem(reference, dsm_crs, t, shape, geoid=geoid, what="reference DEM").heights
    both = np.isfinite(ref) & np.isfinite(dem)
    if both.sum() < MIN_CELLS:
        raise InputError(f"the DSM and the reference share {int(both.sum())} cells of {t[0]:g} m; "
                         f"need {MIN_CELLS} (does the reference cover the images?)", reference)
    res = dem_offset(ref, dem, t, max_shift_m)
    if not res:
        return RpcDemOrientation(models, [np.zeros_like(m.params) for m in models],
                                 [np.full(m.params.shape, np.nan) for m in models],
                                 (np.nan,) * 3, (np.nan,) * 3, res, float(t[0]))
    s = np.array([res.dx, res.dy, res.dz])
    sig = np.array([res.sigma_dx, res.sigma_dy, res.sigma_dz])
    # ground samples: the coarse cells' centres at the DSM's heights
    rr, cc = np.nonzero(np.isfinite(dem))
    E = t[2] + t[0] * (cc + 0.5)
    N = t[5] + t[4] * (rr + 0.5)
    H = dem[rr, cc]
    inv = to_lonlat(dsm_crs)
    out, change, sigma = [], [], []
    for m in models:
        kind = m.kind if BIAS_MODELS[m.kind] > BIAS_MODELS[bias] else bias
        new, G = _refit(m, kind, E, N, H, s, inv)
        cov = G @ np.diag(sig ** 2) @ G.T
        old = _params_as(m, kind)
        out.append(new)
        change.append(new.params - old)
        sigma.append(np.sqrt(np.diag(cov)))
    return RpcDemOrientation(out, change, sigma, tuple(s), tuple(sig), res, float(t[0]))


def _failed(models, t, reason: str) -> RpcDemOrientation:
    """A co-registration not made (``reason``): the input models, no change."""
    nan = float("nan")
    res = CoregResult(*(nan,) * 10, 0, 0, nan, nan, nan, nan, False, reason)
    return RpcDemOrientation(models, [np.zeros_like(m.params) for m in models],
                             [np.full(m.params.shape, np.nan) for m in models], (nan,) * 3, (nan,) * 3, res,
                             float(t[0]))


def _params_as(m: BiasedRpc, kind: str) -> np.ndarray:
    """``m``'s bias in the parameters of ``kind`` (same reference point; the models nest)."""
    names = {"none": [], "shift": ["a0", "b0"], "shift_drift": ["a0", "b0", "b2"],
             "affine": ["a0", "a1", "a2", "b0", "b1", "b2"]}
    have = dict(zip(names[m.kind], m.params))
    return np.array([have.get(n, 0.0) for n in names[kind]])


def _refit(m: BiasedRpc, kind: str, E, N, H, s, inv):
    """The bias of ``kind`` with ``Δ'(xy) = xy − rpc(X + s)`` at the image points ``xy`` of the
    DSM's ground points ``X``, and its Jacobian ``G`` (p, 3) by the shift (px per m)."""
    lon, lat = inv(E, N)
    x, y = m.project(lon, lat, H)
    x0, y0 = (m.x0, m.y0) if m.kind != "none" else (float(np.mean(x)), float(np.mean(y)))
    D = bias_design(kind, x, y, x0, y0).transpose(1, 0, 2).reshape(-1, BIAS_MODELS[kind])
    P = np.linalg.pinv(D)

    def fit(shift):
        lo, la = inv(E + shift[0], N + shift[1])
        rx, ry = m.rpc.project(lo, la, H + shift[2])
        return P @ np.concatenate([x - rx, y - ry])

    p = fit(s)
    G = np.column_stack([(fit(s + 0.5 * e) - fit(s - 0.5 * e)) for e in np.eye(3)])
    return BiasedRpc(m.rpc, kind, p, x0, y0), G


def ground_sample_distance(model) -> float:
    """Metres on the ground of one pixel along the columns at the RPC's centre and height
    offset (the smaller of the two axes)."""
    r = as_biased(model).rpc
    x0, y0 = r.samp_off + 0.5, r.line_off + 0.5
    lon, lat = r.localize(np.array([x0, x0 + 1.0, x0]), np.array([y0, y0, y0 + 1.0]), np.full(3, r.h_off))
    ke, kn = metres_per_degree(lat[0])
    d = np.hypot((lon[1:] - lon[0]) * ke, (lat[1:] - lat[0]) * kn)
    return float(d.min())


def orient_rpc_from_dem(paths, models, reference, *, bias: str = "shift", geoid=None,
                        posting: float | None = None, pairs=None, points=None, height_range=None,
                        max_shift_m: float = DEFAULT_MAX_SHIFT_M, workers=None, progress=None):
    """The relative DSM of the images (:func:`prismstation.ops.rpc_dsm.rpc_dsm`, ``pairs``
    default every pair) at ``posting`` (default 8 pixels: it need only resolve the
    reference's relief) laid on ``reference``: ``(RpcDemOrientation, dsm)``. ``points``
    (lon°, lat°, h m of the tie points), ``height_range``: the DSM's a-priori heights;
    ``geoid``: for an orthometric reference."""
    if posting is None:
        posting = 8.0 * ground_sample_distance(models[0])
    # the search: the tie points' heights and the reference's ± 40 m (the block's vertical
    # error before its orientation, and the reference's own)
    dsm, _ = rpc_dsm(paths, models, posting=posting, pairs=pairs, points=points, reference=reference,
                     geoid=geoid, height_range=height_range, workers=workers, progress=progress)
    return orient_from_reference(models, dsm.heights, dsm.transform, dsm.crs, reference, bias=bias,
                                 geoid=geoid, max_shift_m=max_shift_m), dsm
