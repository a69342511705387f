"""Step 1 of the DEM orientation: where F and B really are relative to N, from files.

:func:`coarse_view_offsets` reads the reference DEM (ellipsoidal through ``geoid``) over N's
footprint, cuts N into a 3 × 3 lattice of windows, and for each window and view calls
:func:`prismstation.core.orientation.view_offsets.view_offset` over the radius the a-priori σ allows; the
windows are combined per view with a consistency verdict. The result's ``offsets_px`` are
N-space pixels from the ancillary prediction to where the view sees the point, at N's centre,
and ``gradients_px`` how they vary over N (attitude drift): the DEM orientation
(:mod:`prismstation.ops.orient_dem`) removes them before its per-patch matching.

A-priori: ``sigma_apriori_m`` (each view's geolocation σ per component, metres; default 50 m
after the ~50 m shifts Gonçalves reports with SRTM as control), ``k`` = 3 (search radius ``k·σ·√2 / GSD``),
``sigma_height_m`` (reference heights, see ``view_offset``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from prismstation.core.orientation import view_offsets as vo
from prismstation.core.matching.coarse import K_SIGMA, search_radius_px
from prismstation.core.models.scene import Scene
from prismstation.errors import InputError
from prismstation.io.dem import read_dem
from prismstation.io.windows import open_image
from prismstation.ops.progress import checkpoint

SIGMA_APRIORI_M = 50.0
#: the smallest N window the coarse search is cut into (px): a larger a-priori σ leaves no room
MIN_WINDOW_PX = 32


@dataclass(frozen=True)
class CoarseOffsets:
    """Per view (F, B): the N-space offset (px) at the N image's centre, its σ, the verdict,
    the windows, and the offset's gradient over N (px per N pixel, 2 × 2,
    :func:`prismstation.core.orientation.view_offsets.gradient`)."""

    offsets_px: dict
    sigma_px: dict
    verdicts: dict
    windows: tuple
    sigma_apriori_m: float
    radius_px: float
    gradients_px: dict | None = None

    def ok(self, view: str) -> bool:
        return bool(np.isfinite(self.offsets_px[view]).all())

    def to_dict(self) -> dict:
        def num(v):
            return float(v) if np.isfinite(v) else None
        return {"sigma_apriori_m": self.sigma_apriori_m, "radius_px": self.radius_px,
                "offsets_px": {v: [num(c) for c in o] for v, o in self.offsets_px.items()},
                "gradients_px": {v: [[num(c) for c in row] for row in np.asarray(g)]
                                 for v, g in (self.gradients_px or {}).items()},
                "sigma_px": {v: [num(c) for c in s] for v, s in self.sigma_px.items()},
                "verdicts": {v: (x.to_dict() if x is not None else None) for v, x in self.verdicts.items()},
                "windows": [{"view": w.view, "n_window": list(w.n_window), "dx": num(w.dx),
                             "dy": num(w.dy), "sigma_dx": num(w.sigma_dx), "sigma_dy": num(w.sigma_dy),
                             "status": w.status, "reason": w.reason, "score": num(w.score)}
                            for w in self.windows]}


def coarse_view_offsets(scene: Scene, reference_path, geoid, *, sigma_apriori_m: float = SIGMA_APRIORI_M,
                        k: float = K_SIGMA, window_px: int = 512, grid: int = 3,
                        posting_m: float = 30.0, n_shift=None, progress=None) -> CoarseOffsets:
    """F and B offsets relative to N over the a-priori range (module docstring); ``n_shift``
    as in :func:`prismstation.core.orientation.view_offsets.n_heights` (N's error, once known)."""
    if not scene.is_triplet:
        raise InputError("the coarse view offsets need an N, F, B triplet")
    N = scene.views["N"]
    rows, cols = N.shape
    radius = search_radius_px(sigma_apriori_m * np.sqrt(2), N.pixel_size_m, k)
    if not min(rows, cols) - 2 * (radius + 24) >= MIN_WINDOW_PX:
        raise InputError(f"an a-priori geolocation σ of {sigma_apriori_m:g} m asks for a search of {radius:.0f} px "
                         f"each way ({k:g} σ of F − N and B − N), more than N's {cols} × {rows} px can hold "
                         f"with a window inside it: a smaller σ, or a larger scene")
    margin = int(radius) + 24
    corners = N.map_to_image.inverse()(np.array([[0, 0], [cols, 0], [0, rows], [cols, rows]], float))
    pad = 1000.0 + 3 * sigma_apriori_m
    lo, hi = corners.min(0) - pad, corners.max(0) + pad
    shape = (int((hi[1] - lo[1]) // posting_m) + 1, int((hi[0] - lo[0]) // posting_m) + 1)
    ref = read_dem(reference_path, scene.crs, (posting_m, 0.0, lo[0], 0.0, -posting_m, hi[1]), shape,
                   geoid=geoid)
    if not np.isfinite(ref.heights).any():
        raise InputError("the reference DEM does not cover the scene", reference_path)
    mean_h = float(np.nanmean(ref.heights))
    filled = np.where(np.isfinite(ref.heights), ref.heights, mean_h)

    def sample(e, n):
        return ndimage.map_coordinates(filled, [(hi[1] - n) / posting_m - 0.5, (e - lo[0]) / posting_m - 0.5],
                                       order=1, mode="nearest")

    wins = vo.lattice((rows, cols), window_px, k=grid, margin_px=margin)
    found = []
    ds = {v: open_image(scene.views[v].image, f"view {v}") for v in "NFB"}
    try:
        for i, win in enumerate(wins):
            checkpoint(progress, i / len(wins), f"coarse offsets: window {i + 1} of {len(wins)}")
            c0, r0, w, h = win
            n_img = ds["N"].read_padded(c0, r0, w, h)
            if not np.isfinite(n_img).all():
                continue
            hh = vo.n_heights(scene, win, sample, mean_h, n_shift=n_shift)
            for v in "FB":
                a0, b0, aw, ah = vo.source_window(scene, v, win, hh, radius + 12)
                found.append(vo.view_offset(scene, v, n_img, win, ds[v].read_padded(a0, b0, aw, ah),
                                            (a0, b0), hh, sigma_apriori_m, k))
    finally:
        for d in ds.values():
            d.close()
    offsets, sigmas, verdicts, grads = {}, {}, {}, {}
    for v in "FB":
        mine = [o for o in found if o.view == v]
        _, sigmas[v], verdicts[v] = vo.combine(mine)
        offsets[v], grads[v] = vo.gradient(mine, (cols / 2, rows / 2))
    checkpoint(progress, 1.0, "coarse offsets done")
    return CoarseOffsets(offsets, sigmas, verdicts, tuple(found), float(sigma_apriori_m), float(radius),
                         grads)
