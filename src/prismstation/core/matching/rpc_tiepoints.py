"""Tie points matched automatically between images of one block, for the RPC bias fit.

SIFT keypoints of a reference image matched to each other image (Lowe's ratio test, then a
fundamental-matrix RANSAC to drop gross mismatches: over a crop of a few thousand pixels a
pushbroom pair's epipolar geometry is close to a perspective one's), each match refined to
sub-pixel by NCC and least-squares matching (:func:`prismstation.core.matching.matching.match_point`,
whose σ is calibrated on real Pléiades imagery). Points are thinned to one per grid cell so they
spread over the images. Image coordinates are the project's (pixel centre at +0.5; OpenCV's
keypoints have it at 0 and are moved).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.core.matching.matching import match_point


@dataclass(frozen=True, eq=False)
class TiePoints:
    """``point``, ``image`` ``(m,)`` and ``xy`` ``(m, 2)`` px, ``sigma`` ``(m, 2)`` px: the
    observations :func:`prismstation.core.models.rpc_adjust.adjust` takes; ``n_points`` points, each
    seen in the reference image and at least one other."""

    point: np.ndarray
    image: np.ndarray
    xy: np.ndarray
    sigma: np.ndarray
    n_points: int


def to_uint8(img: np.ndarray) -> np.ndarray:
    """Stretch the 1–99 % range of any numeric image to 0–255 (NaN to 0)."""
    a = np.asarray(img, dtype=np.float32)
    finite = np.isfinite(a)
    lo, hi = np.percentile(a[finite], [1, 99]) if finite.any() else (0.0, 1.0)
    out = np.clip((np.where(finite, a, lo) - lo) * (255.0 / max(hi - lo, 1e-6)), 0, 255)
    return out.astype(np.uint8)


def match_tie_points(images: Sequence[np.ndarray], ref: int = 0, *, cell: int = 32,
                     ratio: float = 0.75, ransac_px: float = 2.0, half_window: int = 12,
                     search_px: float = 3.0, min_score: float = 0.7,
                     max_sigma: float = 0.3) -> TiePoints:
    """Tie points between ``images[ref]`` and every other image.

    ``cell`` px: at most one point per cell of the reference image; ``ransac_px`` the
    fundamental-matrix RANSAC threshold; the sub-pixel match searches ``±search_px`` around the
    SIFT position with a ``(2·half_window + 1)²`` template. Each observation's σ is the
    calibrated match σ divided by √2 in both images (the match measures their difference).
    """
    sift = cv2.SIFT_create()
    u8 = [to_uint8(im) for im in images]
    kp_ref, des_ref = sift.detectAndCompute(u8[ref], None)
    pts_ref = np.array([k.pt for k in kp_ref], dtype=np.float64) + 0.5
    resp = np.array([k.response for k in kp_ref])
    # one keypoint per cell, the strongest
    cells = (pts_ref[:, 1] // cell).astype(int) * 100000 + (pts_ref[:, 0] // cell).astype(int)
    order = np.lexsort((-resp, cells))
    keep = order[np.r_[True, cells[order][1:] != cells[order][:-1]]]
    allowed = np.zeros(len(kp_ref), bool)
    allowed[keep] = True
    matcher = cv2.BFMatcher(cv2.NORM_L2)
    found: dict[int, dict[int, tuple]] = {}
    for k, im in enumerate(u8):
        if k == ref:
            continue
        kp, des = sift.detectAndCompute(im, None)
        if des is None or len(kp) < 8:
            continue
        pairs = [(m.queryIdx, m.trainIdx) for m, n2 in
                 (p for p in matcher.knnMatch(des_ref, des, k=2) if len(p) == 2)
                 if m.distance < ratio * n2.distance]
        if len(pairs) < 8:
            continue
        q = np.array([p[0] for p in pairs])
        t = np.array([p[1] for p in pairs])
        a = pts_ref[q]
        b = np.array([kp[i].pt for i in t], dtype=np.float64) + 0.5
        _, inl = cv2.findFundamentalMat(a, b, cv2.FM_RANSAC, ransac_px, 0.999)
        if inl is None:
            continue
        for qi, bi in zip(q[inl.ravel() == 1], b[inl.ravel() == 1]):
            if not allowed[qi]:
                continue
            r = match_point(images[ref], pts_ref[qi, 0], pts_ref[qi, 1], images[k], bi[0], bi[1],
                            search_range=search_px, half_window=half_window,
                            min_score=min_score, max_sigma=max_sigma)
            if r.ok:
                found.setdefault(int(qi), {})[k] = (r.x, r.y, r.sigma_x, r.sigma_y)
    P, I, XY, S = [], [], [], []
    for j, (qi, seen) in enumerate(sorted(found.items())):
        s_ref = np.mean([[v[2], v[3]] for v in seen.values()], axis=0) / np.sqrt(2)
        P.append(j), I.append(ref), XY.append(pts_ref[qi]), S.append(s_ref)
        for k, (x, y, sx, sy) in sorted(seen.items()):
            P.append(j), I.append(k), XY.append((x, y)), S.append((sx / np.sqrt(2), sy / np.sqrt(2)))
    return TiePoints(np.array(P, int), np.array(I, int), np.array(XY, float).reshape(-1, 2),
                     np.array(S, float).reshape(-1, 2), len(found))
