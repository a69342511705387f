"""DEM-to-DEM co-registration by least-squares surface matching, and affine shift fields.

Grid convention: both DEMs are 2-D arrays on ONE grid (rows, cols), NaN where void; the
grid's affine ``transform = (a, b, c, d, e, f)`` (rasterio ``Affine`` order) maps a grid
position ``(col, row)`` (docs/model.md §1: pixel centre at ``i + 0.5``) to CRS coordinates
``x = a·col + b·row + c``, ``y = d·col + e·row + f``.

Shift convention (docs/formats.md, ``coregister``): ``(dcol, drow)`` is what to add to the DEM's
pixel positions to lay it on the reference, and ``dz`` is added to its heights::

    reference(col, row) ≈ dem(col - dcol, row - drow) + dz

so a DEM whose content sits 3 columns left of and 5 rows above where the reference has it
gives ``dcol = 3, drow = 5``.

The estimator is least-squares surface matching restricted to a 3-D translation (Gruen &
Akca 2005): Gauss–Newton on the height differences, linearised with the gradients of the
shifted DEM, outliers (beyond ``k``·NMAD) and very steep cells left out, run coarse-to-fine
on a block-averaged pyramid so that multi-pixel shifts converge. σ's come from
``σ0²·(AᵀA)⁻¹`` multiplied by the residuals' correlation area (:func:`correlation_area`):
height errors of neighbouring cells are correlated, and a per-cell adjustment that ignored it
would claim σ's many times too small. The shift is interpolated bilinearly, which biases
sub-pixel shifts by up to ~0.01 px on real terrain: a floor below which σ's are not claims.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prismstation.core.adjustment.stats import nmad

IDENTITY = (1.0, 0.0, 0.0, 0.0, -1.0, 0.0)
#: σ (px) added in quadrature to the horizontal shift (and, half of it times the RMS slope in m
#: per pixel, to dz): the bias of bilinear interpolation, measured on SRTM 3″ (≤ 0.005 px, 0.12 m)
INTERP_FLOOR_PX = 0.01


@dataclass(frozen=True)
class CoregResult:
    """3-D shift laying a DEM on a reference DEM (see the module docstring for signs).

    Attributes
    ----------
    dcol, drow : float
        Shift in reference-grid pixels (add to the DEM's pixel positions).
    dx, dy : float
        The same shift in CRS units (x east, y north for a north-up grid).
    dz : float
        Height shift (metres), added to the DEM's heights.
    sigma_dcol, sigma_drow, sigma_dx, sigma_dy, sigma_dz : float
        Formal standard deviations from the adjustment.
    iterations : int
        Gauss–Newton iterations, all pyramid levels together.
    count : int
        Cells used in the final adjustment.
    nmad_before, nmad_after, mean_after, std_after : float
        Statistics of ``reference − dem`` before and after applying the shift (metres).
    converged : bool
        Whether the finest level converged within ``max_iter``, inside the a-priori bound,
        with finite σ's and the DEMs agreeing better after the shift than before.
    reason : str
        Why it did not converge ("" when it did).
    """

    dcol: float
    drow: float
    dx: float
    dy: float
    dz: float
    sigma_dcol: float
    sigma_drow: float
    sigma_dx: float
    sigma_dy: float
    sigma_dz: float
    iterations: int
    count: int
    nmad_before: float
    nmad_after: float
    mean_after: float
    std_after: float
    converged: bool
    reason: str = ""

    def __bool__(self) -> bool:
        """False when no shift was found (``reason`` says why): the failure convention of
        :mod:`prismstation.core.adjustment.estimate`."""
        return bool(self.converged)


def _grids(reference, dem, transform) -> tuple[np.ndarray, np.ndarray, float]:
    """``(reference, dem, pixel)``: the two 2-D float grids of one shape and the grid's cell
    size (m, the square root of the transform's cell area)."""
    ref, dm = np.asarray(reference, float), np.asarray(dem, float)
    if ref.shape != dm.shape or ref.ndim != 2:
        raise ValueError(f"reference {ref.shape} and dem {dm.shape} must be 2-D arrays on one grid")
    a, b, _, d, e, _ = (float(t) for t in tuple(transform)[:6])
    return ref, dm, float(np.sqrt(abs(a * e - b * d)))

def shift_grid(a: np.ndarray, dcol: float, drow: float) -> np.ndarray:
    """Return ``out(col, row) = a(col − dcol, row − drow)``, bilinear, NaN outside or near voids.

    Parameters
    ----------
    a : ndarray (rows, cols), float
    dcol, drow : float
        Shift in pixels.
    """
    a = np.asarray(a, float)
    rows, cols = a.shape
    ic, fc = int(np.floor(dcol)), dcol - np.floor(dcol)
    ir, fr = int(np.floor(drow)), drow - np.floor(drow)

    def take(sr, sc):                     # a[r - sr, c - sc] for all r, c (NaN outside)
        out = np.full((rows, cols), np.nan)
        r_lo, r_hi = max(0, sr), min(rows, rows + sr)
        c_lo, c_hi = max(0, sc), min(cols, cols + sc)
        if r_lo < r_hi and c_lo < c_hi:
            out[r_lo:r_hi, c_lo:c_hi] = a[r_lo - sr:r_hi - sr, c_lo - sc:c_hi - sc]
        return out

    out = np.zeros((rows, cols))
    for sr, wr in ((ir, 1 - fr), (ir + 1, fr)):           # zero weights skipped: no NaN leak
        for sc, wc in ((ic, 1 - fc), (ic + 1, fc)):
            if wr * wc > 0:
                out += wr * wc * take(sr, sc)
    return out


def block_mean(a: np.ndarray, f: int) -> np.ndarray:
    """Block mean by ``f`` (NaN where a block has fewer than half valid cells)."""
    if f == 1:
        return a
    rows, cols = (a.shape[0] // f) * f, (a.shape[1] // f) * f
    blocks = a[:rows, :cols].reshape(rows // f, f, cols // f, f)
    valid = np.isfinite(blocks).sum(axis=(1, 3))
    with np.errstate(invalid="ignore"):
        mean = np.nansum(blocks, axis=(1, 3)) / np.maximum(valid, 1)
    mean[valid < f * f / 2] = np.nan
    return mean


def _lsm_level(ref, dem, dcol, drow, dz, max_iter, tol, k_outlier, max_slope, bound=np.inf):
    """Gauss–Newton on one level; returns (dcol, drow, dz, cov, iterations, count, converged).
    Stops (not converged) when the shift leaves ``bound`` pixels or stops being finite."""
    cov, count, converged = np.full((3, 3), np.nan), 0, False
    it = 0
    for it in range(1, max_iter + 1):
        if not (np.isfinite([dcol, drow, dz]).all() and np.hypot(dcol, drow) <= bound):
            break
        s = shift_grid(dem, dcol, drow)
        gy, gx = np.gradient(s)
        v = ref - s - dz
        ok = np.isfinite(v) & np.isfinite(gx) & np.isfinite(gy)
        if ok.sum() < 10:
            break
        med, spread = np.median(v[ok]), nmad(v[ok])
        ok &= np.abs(v - med) <= k_outlier * max(spread, 1e-9)
        ok &= np.hypot(gx, gy) <= max_slope
        A = np.column_stack([-gx[ok], -gy[ok], np.ones(ok.sum())])
        y = v[ok]
        count = y.size
        if count < 10:
            break
        N = A.T @ A
        try:
            delta = np.linalg.solve(N, A.T @ y)
        except np.linalg.LinAlgError:
            break
        res = y - A @ delta
        cov = float(res @ res) / max(count - 3, 1) * np.linalg.inv(N)
        dcol, drow, dz = dcol + delta[0], drow + delta[1], dz + delta[2]
        if abs(delta[0]) < tol and abs(delta[1]) < tol:
            converged = True
            break
    return dcol, drow, dz, cov, it, count, converged


def coregister(reference: np.ndarray, dem: np.ndarray, transform=IDENTITY, *, levels: int | None = None,
               max_iter: int = 30, tol: float = 1e-3, k_outlier: float = 3.0,
               max_slope_deg: float = 70.0, max_shift: float | None = None) -> CoregResult:
    """Estimate the 3-D shift laying ``dem`` on ``reference`` (least-squares surface matching).

    Parameters
    ----------
    reference, dem : ndarray, shape (rows, cols)
        Heights (metres, same kind) on one grid, NaN where void.
    transform : 6 numbers (a, b, c, d, e, f)
        Grid → METRIC affine (rasterio ``Affine`` order; for a geographic grid use
        ``io.dem.local_metric_transform``); only ``a, b, d, e`` (pixel size in metres and
        rotation) matter: slope thresholds and the shift in metres.
    levels : int, optional
        Pyramid levels (block averaging by 2 per level); default: as many as keep the
        coarsest grid at 48 cells or more on its short side, at most 4, and at least enough
        that ``max_shift`` is within 4 cells of the coarsest level (LSM's pull-in range on
        smooth terrain).
    max_shift : float, optional
        The a-priori bound of the horizontal shift (metres); default a quarter of the
        grid's short side. A shift that leaves it is reported as not converged.
    max_iter, tol : int, float
        Gauss–Newton limit per level and convergence threshold (pixels).
    k_outlier : float
        Cells with a residual beyond ``k_outlier``·NMAD of the median are left out.
    max_slope_deg : float
        Cells steeper than this (from the grid's pixel size) are left out.

    Returns
    -------
    CoregResult
    """
    ref, dm, pixel = _grids(reference, dem, transform)
    bound = (min(ref.shape) / 4 if max_shift is None else float(max_shift) / pixel)
    if levels is None:
        levels = 1
        while levels < 4 and min(ref.shape) // 2 ** levels >= 48:
            levels += 1
        while bound / 2 ** (levels - 1) > 4 and min(ref.shape) // 2 ** levels >= 16:
            levels += 1
    before = ref - dm
    dz = float(np.nanmedian(before)) if np.isfinite(before).any() else 0.0
    dcol = drow = 0.0
    total = 0
    for level in reversed(range(levels)):
        f = 2 ** level
        r_l, d_l = block_mean(ref, f), block_mean(dm, f)
        slope = np.tan(np.radians(max_slope_deg)) * pixel * f
        c, r, dz, cov, it, count, converged = _lsm_level(
            r_l, d_l, dcol / f, drow / f, dz, max_iter, tol / f if level else tol,
            k_outlier, slope, 1.5 * bound / f)
        dcol, drow = c * f, r * f
        total += it
    return _result(ref, dm, transform, dcol, drow, dz, cov, total, count, converged, bound, max_iter)


def correlation_area(res: np.ndarray, max_lag: int = 8) -> float:
    """Correlation area (cells) of a residual grid: the sum of its autocorrelation over lags
    ``|Δcol|, |Δrow| ≤ max_lag`` (1 for white residuals). A mean over ``n`` correlated cells
    has the variance of ``n / area`` independent ones, so formal variances are multiplied by it.
    """
    ok = np.isfinite(res)
    if ok.sum() < 50:
        return 1.0
    v = np.where(ok, res - np.median(res[ok]), 0.0)
    m = ok.astype(float)
    shape = [int(2 ** np.ceil(np.log2(n + max_lag + 1))) for n in v.shape]
    fv, fm = np.fft.rfft2(v, shape), np.fft.rfft2(m, shape)
    num = np.fft.irfft2(fv * np.conj(fv), shape)
    cnt = np.fft.irfft2(fm * np.conj(fm), shape)
    lags = np.r_[0:max_lag + 1, -max_lag:0]
    num, cnt = num[np.ix_(lags, lags)], np.maximum(cnt[np.ix_(lags, lags)], 1.0)
    acov = num / cnt
    rho = acov / acov[0, 0] if acov[0, 0] > 0 else np.zeros_like(acov)
    return float(max(1.0, rho[rho > 0].sum()))


def _verdict(converged, dcol, drow, dz, cov, count, bound, max_iter, before, after,
             relief=np.nan) -> str:
    """Why a shift is not a result ("" when it is)."""
    if not np.isfinite([dcol, drow, dz]).all():
        return "the shift is not finite (the adjustment diverged)"
    if np.hypot(dcol, drow) > bound:
        return (f"the shift ({np.hypot(dcol, drow):.1f} px) leaves the a-priori bound "
                f"({bound:.1f} px): the DEMs do not match within it")
    if count < 10:
        return f"only {count} cells usable (too little overlap, or flat/void terrain)"
    if not converged:
        return f"the adjustment did not converge within {max_iter} iterations"
    if not np.isfinite(np.diag(cov)).all():
        return "the shift's covariance is undetermined"
    if np.isfinite(before) and np.isfinite(after) and after > 1.1 * before + 0.1:
        return f"the shift makes the DEMs agree less (NMAD {before:.1f} → {after:.1f} m)"
    if np.isfinite(relief) and after > 0.5 * relief:
        return (f"the DEMs do not show the same terrain: after the shift they still differ by "
                f"NMAD {after:.1f} m, against {relief:.1f} m of relief spread in the reference")
    return ""


def _result(ref, dm, transform, dcol, drow, dz, cov, total, count, converged,
            bound=np.inf, max_iter=30) -> CoregResult:
    a, b, _, d, e, _ = (float(t) for t in tuple(transform)[:6])
    finite = np.isfinite([dcol, drow, dz]).all()
    after = ref - shift_grid(dm, dcol, drow) - dz if finite else np.full(ref.shape, np.nan)
    fin = after[np.isfinite(after)]
    before_n, after_n = nmad(ref - dm), nmad(after)
    if finite and np.isfinite(cov).all():
        gy, gx = np.gradient(dm)
        slope_rms = float(np.sqrt(np.nanmean(gx ** 2 + gy ** 2))) if np.isfinite(gx).any() else 0.0
        floor = [INTERP_FLOOR_PX, INTERP_FLOOR_PX, 0.5 * INTERP_FLOOR_PX * slope_rms]
        cov = cov * correlation_area(after) + np.diag(np.square(floor))
    jac = np.array([[a, b], [d, e]])
    cov_xy = jac @ cov[:2, :2] @ jac.T
    reason = _verdict(converged, dcol, drow, dz, cov, count, bound, max_iter, before_n, after_n,
                      nmad(ref))
    return CoregResult(
        dcol=float(dcol), drow=float(drow), dx=float(a * dcol + b * drow),
        dy=float(d * dcol + e * drow), dz=float(dz),
        sigma_dcol=float(np.sqrt(cov[0, 0])), sigma_drow=float(np.sqrt(cov[1, 1])),
        sigma_dx=float(np.sqrt(cov_xy[0, 0])), sigma_dy=float(np.sqrt(cov_xy[1, 1])),
        sigma_dz=float(np.sqrt(cov[2, 2])), iterations=int(total), count=int(count),
        nmad_before=before_n, nmad_after=after_n,
        mean_after=float(fin.mean()) if fin.size else float("nan"),
        std_after=float(fin.std()) if fin.size else float("nan"), converged=not reason,
        reason=reason)


def nuth_kaab(reference: np.ndarray, dem: np.ndarray, transform=IDENTITY, *, max_iter: int = 30,
              tol: float = 1e-3, k_outlier: float = 3.0, min_slope_deg: float = 2.0,
              max_slope_deg: float = 70.0) -> CoregResult:
    """Nuth & Kääb (2011): the same shift as :func:`coregister`, by their slope/aspect fit.

    Each iteration fits ``dh / tanα = −δcol·sinψ − δrow·cosψ + c`` over the cells (``dh`` the
    height difference ``reference − dem − dz``, ``α`` the slope and ``ψ`` the aspect of the
    shifted DEM in grid axes), moves the DEM by ``(δcol, δrow)`` and takes ``dz`` as the
    median of ``dh``. Same arguments, conventions and result as :func:`coregister`; flat cells
    (slope below ``min_slope_deg``) are left out. σ's come from the last fit.
    """
    ref, dm, pixel = _grids(reference, dem, transform)
    lo, hi = (np.tan(np.radians(v)) * pixel for v in (min_slope_deg, max_slope_deg))
    dcol = drow = 0.0
    dz = float(np.nanmedian(ref - dm))
    cov, count, converged, it = np.full((3, 3), np.nan), 0, False, 0
    for it in range(1, max_iter + 1):
        s = shift_grid(dm, dcol, drow)
        gy, gx = np.gradient(s)
        t = np.hypot(gx, gy)                            # slope, height per pixel
        dh = ref - s
        ok = np.isfinite(dh) & np.isfinite(t) & (t >= lo) & (t <= hi)
        dz = float(np.median(dh[ok]))
        y = (dh - dz) / np.where(t > 0, t, np.nan)
        ok &= np.abs(y - np.median(y[ok])) <= k_outlier * max(nmad(y[ok]), 1e-9)
        count = int(ok.sum())
        if count < 10:
            break
        psi = np.arctan2(gx[ok], gy[ok])
        A = np.column_stack([-np.sin(psi), -np.cos(psi), np.ones(count)])
        N = A.T @ A
        p = np.linalg.solve(N, A.T @ y[ok])
        res = y[ok] - A @ p
        cov = float(res @ res) / max(count - 3, 1) * np.linalg.inv(N)
        dcol, drow = dcol + p[0], drow + p[1]
        if np.hypot(p[0], p[1]) < tol:
            converged = True
            break
    after = ref - shift_grid(dm, dcol, drow)
    fin = np.isfinite(after)
    dz = float(np.median(after[fin])) if fin.any() else dz
    cov[2, 2] = (1.2533 * nmad(after) / np.sqrt(max(fin.sum(), 1))) ** 2   # σ of a median
    return _result(ref, dm, transform, dcol, drow, dz, cov, it, count, converged)
