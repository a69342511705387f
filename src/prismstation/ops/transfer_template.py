"""The point transfer's template size (:func:`template_half`): as large as the texture around
the point needs to fix it, from the image noise alone, before any match."""
from __future__ import annotations

import numpy as np

from prismstation.core.matching.lsm_sigma import texture_sigma
from prismstation.io.windows import ImageWindows

TEMPLATE_HALVES = (12, 18, 24, 32)
"""Template half sizes (px), tried smallest first: a template grows until its texture can fix
the point in every direction (:func:`template_half`)."""
TEXTURE_SIGMA_PX = 0.05
"""The σ (px) a template's texture must promise from the image noise alone in its weakest
direction (:func:`prismstation.core.matching.lsm_sigma.texture_sigma`) to be used: a third of the
0.15 px a transfer on smooth terrain aims at, leaving the rest to what the noise does not
model (shape, sampling)."""


def template_half(images: ImageWindows, source: str, xy, halves=TEMPLATE_HALVES,
                  target: float = TEXTURE_SIGMA_PX) -> int:
    """The smallest template half size of ``halves`` whose texture around ``xy`` of ``source``
    promises ``target`` px or better in its weakest direction (the largest that fits in the
    image when none does):
    25 × 25 px holds a field's hedges and furrows, but inside a flat parcel, or on one straight
    edge, it holds nothing that fixes the point — on another simulator's triplet a third of the
    points failed so (``texture``, ``shape``), and point-sampled edges fix a position only
    where many of them, at many sub-pixel phases, are averaged."""
    big = images.around(source, xy[0], xy[1], halves[-1] + 2)
    if big[0] is None:
        return halves[0]
    a, c0, r0 = big
    i0, j0 = int(np.floor(xy[0])) - c0, int(np.floor(xy[1])) - r0
    fits = halves[0]
    for h in halves:
        if i0 - h < 0 or j0 - h < 0 or i0 + h + 1 > a.shape[1] or j0 + h + 1 > a.shape[0]:
            break
        fits = h
        if texture_sigma(a[j0 - h:j0 + h + 1, i0 - h:i0 + h + 1]) <= target:
            return h
    return fits
