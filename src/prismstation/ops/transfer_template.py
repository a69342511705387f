"""The point transfer's template size (:func:`template_halves`): as large as the texture around
the point needs to fix it, from the image noise and point sampling, before any match."""
from __future__ import annotations

import numpy as np

from prismstation.core.matching.lsm_sigma import template_sigmas

TEMPLATE_HALVES = (12, 18, 24, 32)
"""Template half sizes (px), tried smallest first: a template grows until its texture can fix
the point in every direction (:func:`template_halves`)."""
SOURCE_MARGIN = 8
"""Pixels of the source view read beyond a template's half size (a smoothed pass's template is
``⌈3 × 1.5⌉`` px larger)."""
TEXTURE_SIGMA_PX = 0.05
"""The σ (px) a template's texture must promise in its weakest direction
(:func:`prismstation.core.matching.lsm_sigma.template_sigmas`) to be used: a third of the
0.15 px a transfer on smooth terrain aims at, leaving the rest to what the template does not
model (shape, relief)."""


def template_halves(window, xy, halves=TEMPLATE_HALVES, target: float = TEXTURE_SIGMA_PX) -> tuple[int, int]:
    """``(with sampling, noise only)``: the smallest template half sizes of ``halves`` whose
    texture around image pixel ``xy`` promises ``target`` px or better in its weakest
    direction — from the image noise and the place of point-sampled edges, and from the noise
    alone (the largest that fits in the image when none does).

    25 × 25 px hold a field's hedges and furrows, but inside a flat parcel, or on one straight
    edge, they hold nothing that fixes the point — on another simulator's triplet a third of the
    points failed so (``texture``, ``shape``) — and where each pixel is one point of the ground
    (no optical blur) an edge lies anywhere between two samples: a position is then the mean
    over many edges' phases.

    ``window``: ``(array, col0, row0)`` of the source view around ``xy`` as
    :meth:`~prismstation.io.windows.ImageWindows.around` returns it, at least
    ``halves[-1] + 3`` px each side where the image has them (the transfer reads it once for
    this and for its templates: :data:`SOURCE_MARGIN`)."""
    a, c0, r0 = window
    if a is None:
        return halves[0], halves[0]
    i0, j0 = int(np.floor(xy[0])) - c0, int(np.floor(xy[1])) - r0
    fit = [h for h in halves if i0 - h - 2 >= 0 and j0 - h - 2 >= 0 and i0 + h + 3 <= a.shape[1]
           and j0 + h + 3 <= a.shape[0]]
    if not fit:
        return halves[0], halves[0]
    m = fit[-1] + 2
    sig = template_sigmas(a[j0 - m:j0 + m + 1, i0 - m:i0 + m + 1], fit, stop=target)
    both = next((h for h, s in zip(fit, sig) if s[1] <= target), fit[-1])
    noise = next((h for h, s in zip(fit, sig) if s[0] <= target), fit[-1])
    return both, noise

