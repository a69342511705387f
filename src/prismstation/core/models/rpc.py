"""The rational function model (RPC00B) of a pushbroom image: ground ↔ image, with partials.

Ground points are longitude and latitude in degrees (WGS 84; a longitude differs from the RPC's
``LONG_OFF`` by less than half a turn, so an image across the antimeridian sees −179.9° and
180.1° alike, and image → ground returns −180…180°) and ellipsoidal height in metres;
image points are ``x`` = column and ``y`` = row in pixels, the project's convention: origin at
the top-left *corner* of the top-left pixel, so the centre of pixel ``(i, j)`` is
``(i + 0.5, j + 0.5)``. RPCs count from the *centre* of the first pixel (``SAMP_OFF`` and
``LINE_OFF`` of the NITF RPC00B standard, 0-based as GDAL reads them), so
``x = sample + 0.5`` and ``y = line + 0.5`` — the same numbers GDAL's RPC transformer returns.

Terms in RPC00B order (L = longitude, P = latitude, H = height, each normalised by its offset
and scale): 1, L, P, H, LP, LH, PH, L², P², H², PLH, L³, LP², LH², L²P, P³, PH², L²H, P²H, H³.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from prismstation.errors import ModelError

#: names of the ten scalar fields, in the order of :meth:`Rpc.offsets_scales`
SCALARS = ("line_off", "samp_off", "lat_off", "lon_off", "h_off",
           "line_scale", "samp_scale", "lat_scale", "lon_scale", "h_scale")
#: the four 20-coefficient polynomials
POLYNOMIALS = ("line_num", "line_den", "samp_num", "samp_den")
#: the range each offset and scale may take on Earth (degrees, metres, pixels); outside it an
#: RPC is refused: heights from below the Dead Sea to above Everest with margin, images of up to
#: ten million pixels a side
PLAUSIBLE = {"lat_off": (-90.0, 90.0), "lon_off": (-360.0, 360.0), "lat_scale": (-90.0, 90.0),
             "lon_scale": (-180.0, 180.0), "h_off": (-1000.0, 10000.0), "h_scale": (-10000.0, 10000.0),
             "line_off": (-1e7, 1e7), "samp_off": (-1e7, 1e7), "line_scale": (-1e7, 1e7),
             "samp_scale": (-1e7, 1e7)}


def wrap180(lon):
    """Longitudes (degrees) beyond ±180 brought back by a turn; others untouched (bit for bit):
    an RPC whose ``LONG_OFF`` is near the antimeridian sees −179.9° as 180.1°."""
    lon = np.asarray(lon, dtype=float)
    return np.where(lon > 180.0, lon - 360.0, np.where(lon < -180.0, lon + 360.0, lon))


def _terms(L, P, H):
    """The 20 RPC00B monomials, shape ``(20, *L.shape)``."""
    one = np.ones_like(L)
    return np.stack([one, L, P, H, L * P, L * H, P * H, L * L, P * P, H * H,
                     P * L * H, L ** 3, L * P * P, L * H * H, L * L * P, P ** 3, P * H * H,
                     L * L * H, P * P * H, H ** 3])


def _dterms(L, P, H):
    """Derivatives of the 20 monomials by L, P and H, each ``(20, *L.shape)``."""
    z, one = np.zeros_like(L), np.ones_like(L)
    dL = np.stack([z, one, z, z, P, H, z, 2 * L, z, z, P * H, 3 * L * L, P * P, H * H,
                   2 * L * P, z, z, 2 * L * H, z, z])
    dP = np.stack([z, z, one, z, L, z, H, z, 2 * P, z, L * H, z, 2 * L * P, z, L * L,
                   3 * P * P, H * H, z, 2 * P * H, z])
    dH = np.stack([z, z, z, one, z, L, P, z, z, 2 * H, P * L, z, z, 2 * L * H, z, z,
                   2 * P * H, L * L, P * P, 3 * H * H])
    return dL, dP, dH


@dataclass(frozen=True, eq=False)
class Rpc:
    """One image's rational polynomial coefficients (RPC00B).

    ``line_off``/``samp_off`` are 0-based with the first pixel's centre at 0 (GDAL's reading
    of the standard); scales and offsets of ground in degrees and ellipsoidal metres; the four
    polynomials ``(20,)`` each. Readers (:mod:`prismstation.io.rpc`) convert other conventions
    (DIMAP's 1-based offsets, a crop's position in the full image) into this one.
    """

    line_off: float
    samp_off: float
    lat_off: float
    lon_off: float
    h_off: float
    line_scale: float
    samp_scale: float
    lat_scale: float
    lon_scale: float
    h_scale: float
    line_num: np.ndarray
    line_den: np.ndarray
    samp_num: np.ndarray
    samp_den: np.ndarray
    #: where the coefficients came from (a file name and the reader), for messages
    source: str = field(default="", compare=False)

    def __post_init__(self):
        for name in POLYNOMIALS:
            c = np.asarray(getattr(self, name), dtype=float)
            if c.shape != (20,) or not np.all(np.isfinite(c)):
                raise ModelError(f"RPC {name}: 20 finite coefficients needed, got shape {c.shape}")
            object.__setattr__(self, name, c)
        for name in SCALARS:
            v = float(getattr(self, name))
            if not np.isfinite(v) or (name.endswith("_scale") and v == 0):
                raise ModelError(f"RPC {name} = {v}: must be finite" +
                                 (" and non-zero" if name.endswith("_scale") else ""))
            object.__setattr__(self, name, v)
        if not np.any(self.line_den) or not np.any(self.samp_den):
            raise ModelError("RPC denominator is all zeros")
        for name, (lo, hi) in PLAUSIBLE.items():
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise ModelError(f"RPC {name} = {v:g} is outside [{lo:g}, {hi:g}]"
                                 + (" (latitude and longitude swapped?)" if name in ("lat_off", "lon_off") else ""))
        g = np.linspace(-1.0, 1.0, 5)  # the denominators over the normalised domain [-1, 1]³
        t = _terms(*np.meshgrid(g, g, g, indexing="ij"))
        for name in ("line_den", "samp_den"):
            den = np.tensordot(getattr(self, name), t, axes=1)
            if not (np.all(den > 0) or np.all(den < 0)):
                where = "at its centre" if getattr(self, name)[0] == 0 else "within its domain"
                raise ModelError(f"RPC {name} is zero {where}: the model divides by zero there")

    # ------------------------------------------------------------------ conversions
    def offsets_scales(self) -> tuple[float, ...]:
        return tuple(getattr(self, n) for n in SCALARS)

    def shifted(self, dx: float = 0.0, dy: float = 0.0) -> "Rpc":
        """The same RPC with image coordinates moved: ``x' = x + dx``, ``y' = y + dy``
        (a crop starting at full-image pixel ``(c, r)`` is ``shifted(-c, -r)``)."""
        return replace(self, samp_off=self.samp_off + dx, line_off=self.line_off + dy)

    def to_gdal_dict(self) -> dict:
        """GDAL's RPC metadata keys (``rasterio.rpc.RPC.from_gdal`` reads them)."""
        d = {"LINE_OFF": self.line_off, "SAMP_OFF": self.samp_off, "LAT_OFF": self.lat_off,
             "LONG_OFF": self.lon_off, "HEIGHT_OFF": self.h_off, "LINE_SCALE": self.line_scale,
             "SAMP_SCALE": self.samp_scale, "LAT_SCALE": self.lat_scale,
             "LONG_SCALE": self.lon_scale, "HEIGHT_SCALE": self.h_scale}
        for key, name in zip(("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF",
                              "SAMP_DEN_COEFF"), POLYNOMIALS):
            d[key] = " ".join(repr(float(c)) for c in getattr(self, name))
        return {k: (v if isinstance(v, str) else repr(float(v))) for k, v in d.items()}

    # ------------------------------------------------------------------ model
    def _normalise(self, lon, lat, h):
        lon, lat, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (lon, lat, h)))
        return ((wrap180(lon - self.lon_off)) / self.lon_scale, (lat - self.lat_off) / self.lat_scale,
                (h - self.h_off) / self.h_scale)

    def project(self, lon, lat, h) -> tuple[np.ndarray, np.ndarray]:
        """Ground ``(lon°, lat°, h m ellipsoidal)`` (broadcastable) → image ``(x, y)`` pixels."""
        L, P, H = self._normalise(lon, lat, h)
        T = _terms(L, P, H)
        line = np.tensordot(self.line_num, T, 1) / np.tensordot(self.line_den, T, 1)
        samp = np.tensordot(self.samp_num, T, 1) / np.tensordot(self.samp_den, T, 1)
        return (samp * self.samp_scale + self.samp_off + 0.5,
                line * self.line_scale + self.line_off + 0.5)

    def project_with_partials(self, lon, lat, h):
        """``x, y`` as :meth:`project` and ``J`` ``(..., 2, 3)``: ∂(x, y)/∂(lon, lat, h) in
        pixels per degree, per degree and per metre (analytic)."""
        L, P, H = self._normalise(lon, lat, h)
        T = _terms(L, P, H)
        dT = _dterms(L, P, H)
        out, rows = [], []
        for num, den, scale, off in ((self.samp_num, self.samp_den, self.samp_scale, self.samp_off),
                                     (self.line_num, self.line_den, self.line_scale, self.line_off)):
            n, d = np.tensordot(num, T, 1), np.tensordot(den, T, 1)
            out.append(n / d * scale + off + 0.5)
            rows.append(np.stack([(np.tensordot(num, dk, 1) * d - n * np.tensordot(den, dk, 1))
                                  / (d * d) * scale / s
                                  for dk, s in zip(dT, (self.lon_scale, self.lat_scale,
                                                        self.h_scale))], axis=-1))
        return out[0], out[1], np.stack(rows, axis=-2)

    def localize(self, x, y, h, *, tol: float = 1e-7, max_iter: int = 30):
        """Image ``(x, y)`` pixels at ellipsoidal height ``h`` m → ``(lon°, lat°)``.

        Newton on :meth:`project` (2 × 2 in lon, lat) from an affine first guess; converged
        where the point re-projects within ``tol`` pixels. Raises :class:`ModelError` naming
        how many points did not converge — never returns a point that does not re-project.
        """
        lon, lat, ok = self.localize_masked(x, y, h, tol=tol, max_iter=max_iter)
        if not np.all(ok):
            bad = int(np.size(ok) - np.count_nonzero(ok))
            raise ModelError(f"RPC image → ground ({self.source or 'RPC'}): {bad} of {np.size(ok)} "
                             f"points did not converge to {tol:g} px in {max_iter} iterations "
                             "(far outside the RPC's validity domain?)")
        return lon, lat

    def localize_masked(self, x, y, h, *, tol: float = 1e-7, max_iter: int = 30):
        """As :meth:`localize` but returns ``(lon, lat, ok)``: NaN and ``ok = False`` where
        Newton did not converge."""
        x, y, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, h)))
        lon, lat = self._first_guess(x, y, h)
        ok = np.zeros(x.shape, bool)
        for _ in range(max_iter):
            px, py, J = self.project_with_partials(lon, lat, h)
            ex, ey = x - px, y - py
            ok = np.hypot(ex, ey) <= tol
            if np.all(ok | ~np.isfinite(ex)):
                break
            a, b, c, d = J[..., 0, 0], J[..., 0, 1], J[..., 1, 0], J[..., 1, 1]
            det = a * d - b * c
            with np.errstate(divide="ignore", invalid="ignore"):
                lon = lon + np.where(ok, 0.0, (d * ex - b * ey) / det)
                lat = lat + np.where(ok, 0.0, (a * ey - c * ex) / det)
        px, py = self.project(lon, lat, h)
        ok = np.isfinite(px) & (np.hypot(x - px, y - py) <= tol)
        return np.where(ok, wrap180(lon), np.nan), np.where(ok, lat, np.nan), ok

    def _first_guess(self, x, y, h):
        """Affine image → ground fitted on a 5 × 5 grid of the ground domain at the points'
        mean height (Newton does the rest)."""
        g = np.linspace(-1.0, 1.0, 5)
        L, P = np.meshgrid(g, g)
        lon = (L * self.lon_scale + self.lon_off).ravel()
        lat = (P * self.lat_scale + self.lat_off).ravel()
        hm = float(np.nanmean(h)) if h.size else self.h_off
        gx, gy = self.project(lon, lat, hm)
        A = np.column_stack([np.ones_like(gx), gx - self.samp_off, gy - self.line_off])
        coef, *_ = np.linalg.lstsq(A, np.column_stack([lon, lat]), rcond=None)
        B = np.stack([np.ones_like(x), x - self.samp_off, y - self.line_off], axis=-1)
        guess = B @ coef
        return guess[..., 0], guess[..., 1]
