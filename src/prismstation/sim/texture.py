"""Ground texture of the simulator.

``fields`` (:func:`make_texture`, the default): a believable landscape as a north-up uint8
grid of 2.5 m cells — field patchworks in two orientations with hedges and ploughing stripes,
forest on steep and wet ground, bare rock on the summits, two road networks, brightness noise at
several scales, all multiplied by hill shading from a sun direction; generated in row blocks
(bounded memory). ``parcels`` (:class:`ParcelTexture`): flat parcels with hard edges, a function
of map position with no grid, so that pixels sampled without a point spread alias;
``mottled`` (:data:`MOTTLED`): larger parcels of lower contrast with a faint grain inside, as
another renderer's parcels were measured.
"""
from __future__ import annotations

from prismstation.core.lazy_cv2 import cv2  # imported at first use: start-up saving
import numpy as np

from prismstation.sim.terrain import Grid

_PERIOD = 1024  # cells of a wrapped value-noise lattice


class _Noise:
    """Smooth value noise of feature size ``scale`` (m), ~unit variance, wrapped."""

    def __init__(self, rng, scale: float, cells: int = _PERIOD):
        self.scale = scale
        self.lattice = rng.standard_normal((cells, cells)).astype(np.float32)
        self._grad = None

    def _remap(self, arr, x, y):
        return cv2.remap(arr, (x / self.scale).astype(np.float32),
                         (y / self.scale).astype(np.float32), cv2.INTER_CUBIC,
                         borderMode=cv2.BORDER_WRAP)

    def __call__(self, x, y):
        return self._remap(self.lattice, x, y)

    def gradient_norm(self, x, y):
        if self._grad is None:
            gy, gx = np.gradient(self.lattice)
            self._grad = (gx / self.scale, gy / self.scale)
        return np.hypot(self._remap(self._grad[0], x, y), self._remap(self._grad[1], x, y))


class _Fields:
    """Parcels on a rotated, warped lattice: per-parcel brightness, hedges, stripes."""

    def __init__(self, rng, angle, size_u, size_v):
        self.c, self.s = float(np.cos(angle)), float(np.sin(angle))
        self.lu, self.lv = size_u, size_v
        self.table = rng.uniform(0, 1, (256, 256, 3)).astype(np.float32)
        self.warp = (_Noise(rng, 350.0, 256), _Noise(rng, 350.0, 256))

    def __call__(self, x, y):
        u = self.c * x + self.s * y + 35.0 * self.warp[0](x, y)
        v = -self.s * x + self.c * y + 35.0 * self.warp[1](x, y)
        fu, fv = u / self.lu, v / self.lv
        # per-parcel random values: nearest lattice cell (cell i covers [i, i+1))
        cell = cv2.remap(self.table, fu - 0.5, fv - 0.5, cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_WRAP)
        crop = 0.36 + 0.44 * cell[..., 0] ** 1.3
        stripes = np.where(cell[..., 1] > 0.55,
                           0.05 * np.sin(v * (2 * np.pi) / (4.0 + 6.0 * cell[..., 2])), 0)
        ru, rv = fu - np.floor(fu), fv - np.floor(fv)
        du = np.minimum(ru, 1 - ru) * self.lu
        dv = np.minimum(rv, 1 - rv) * self.lv
        hedge = np.minimum(du, dv) < 1.6
        return np.where(hedge, 0.5 * crop, crop + stripes).astype(np.float32)


def make_texture(rng, e0: float, n0: float, shape, spacing: float, heights: Grid,
                 shade: Grid, slope: Grid, block_rows: int | None = None, progress=None) -> Grid:
    """uint8 ground texture grid over ``shape`` cells of ``spacing`` m from (e0, n0).

    ``heights`` orthometric (m), ``shade`` (≈1 flat) and ``slope`` (tan) grids drive land
    cover and shading.
    """
    f1 = _Fields(rng, rng.uniform(0, np.pi), rng.uniform(90, 200), rng.uniform(60, 130))
    f2 = _Fields(rng, rng.uniform(0, np.pi), rng.uniform(120, 260), rng.uniform(50, 110))
    region, forest_n = _Noise(rng, 1800.0, 512), _Noise(rng, 700.0, 512)
    crowns, crowns2 = _Noise(rng, 4.0), _Noise(rng, 11.0)
    rock1, rock2 = _Noise(rng, 7.0), _Noise(rng, 35.0)
    roads = (_Noise(rng, 1400.0, 256), _Noise(rng, 900.0, 256))
    mod = (_Noise(rng, 60.0, 1024), _Noise(rng, 6.0), _Noise(rng, 2.5))
    stack = np.dstack([heights.values, shade.values, slope.values]).astype(np.float32)
    rows, cols = shape
    block_rows = block_rows or int(max(32, min(512, 3_000_000 // cols)))
    out = np.empty(shape, dtype=np.uint8)
    x = ((np.arange(cols) + 0.5) * spacing).astype(np.float32)
    for r0 in range(0, rows, block_rows):
        r1 = min(rows, r0 + block_rows)
        y = ((np.arange(r0, r1) + 0.5) * spacing).astype(np.float32)
        xx, yy = np.meshgrid(x, y)
        e, n = e0 + xx.astype(np.float64), n0 - yy.astype(np.float64)
        col, row = heights.to_pixel(e, n)
        gh = cv2.remap(stack, col.astype(np.float32), row.astype(np.float32),
                       cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        hgt, shd, slp = gh[..., 0], gh[..., 1], gh[..., 2]
        fields = np.where(region(xx, yy) > 0, f1(xx, yy), f2(xx, yy))
        forest = 0.24 + 0.07 * crowns(xx, yy) + 0.04 * crowns2(xx, yy)
        fscore = forest_n(xx, yy) + 1.0 * slp - 0.85 + 0.15 * crowns2(xx, yy)
        w = np.clip(fscore * 4.0, 0, 1)
        land = (1 - w) * fields + w * forest
        rock = 0.52 + 0.10 * rock1(xx, yy) + 0.07 * rock2(xx, yy)
        wr = np.clip((hgt - 1050.0) / 150.0 + 0.3 * rock2(xx, yy), 0, 1)
        land = (1 - wr) * land + wr * rock
        for net, width in zip(roads, (5.0, 3.5)):
            dist = np.abs(net(xx, yy)) / (net.gradient_norm(xx, yy) + 1e-6)
            land = np.where(dist < width, 0.78 + 0.03 * mod[2](xx, yy), land)
        land *= 1 + 0.07 * mod[0](xx, yy) + 0.04 * mod[1](xx, yy) + 0.03 * mod[2](xx, yy)
        out[r0:r1] = np.clip(land * shd * 230.0, 0, 255).astype(np.uint8)
        if progress:
            progress(r1 / rows)
    return Grid(out, e0, n0, spacing)


GRAIN_M = (4.0, 9.0)
"""Feature sizes (m) of the ``mottled`` parcels' grain: two octaves of value noise."""
MOTTLED = dict(size=150.0, contrast=24.0, grain_dn=(1.5, 1.5))
"""``mottled`` parcels: measured on another renderer's 10 km scene (its N image, 2,000 px
square), beside ``parcels``: edges 55–59 px apart along a row (``parcels`` 39), the parcels'
brightness spread (a 9 px median, every other pixel) 14 DN (24), and inside the parcels, 12 px
from any edge, a grain of 1.13, 0.95 and 1.56 DN in the bands of Gaussians 0.7–2, 2–5 and
5–10 px (with 2 DN of noise, which alone gives 0.68, 0.22 and 0.08; these parcels rendered so:
1.12, 0.91, 1.41), where ``parcels`` hold only their noise at the finest. One octave of 7 m at 1.9 DN
matched those bands as well, but its misfit had minima tenths of a pixel apart at 27 % of the
matches of two views of it (``benchmarks/bench_transfer_minima.py --pairs``), where the other
renderer's scene shows them at 6 %; these two octaves at 2 %."""


class ParcelTexture:
    """Ground brightness of flat parcels with hard edges, as a function of map position (no
    grid: sampled at each pixel's own ground point, edges stay sharp at any resolution).

    Parcels are the Voronoi cells of one seed per ``size`` m square of a jittered lattice; each
    has a brightness of its own (uniform in ``level ± contrast``), slightly modulated over a few
    tens of metres and over kilometres, multiplied by hill shading. Inside a parcel there is no
    texture but that modulation: a template there sees noise. Sampled without a point spread
    (``simulate --psf-px 0``), the edges alias: what one view's pixel grid shows of them is not
    what another's shows.
    """

    def __init__(self, rng, origin, size: float = 100.0, level: float = 115.0, contrast: float = 40.0,
                 shade: Grid | None = None, table: int = 1024, grain_dn=(0.0, 0.0)):
        self.origin = (float(origin[0]), float(origin[1]))
        self.size, self.level, self.contrast, self.shade, self.n = size, level, contrast, shade, table
        self.jitter = rng.uniform(0.0, 1.0, (table, table, 2)).astype(np.float32)
        self.value = rng.uniform(-1.0, 1.0, (table, table)).astype(np.float32)
        self.fine, self.broad = _Noise(rng, 25.0), _Noise(rng, 1500.0, 256)
        # a grain of a few metres (``grain_dn`` DN at each of :data:`GRAIN_M`): what a template
        # inside a parcel can hold on to
        self.grain = [(dn, _Noise(rng, m, 4096)) for dn, m in zip(grain_dn, GRAIN_M) if dn > 0]

    def __call__(self, e, n) -> np.ndarray:
        """Brightness (DN, float32) at map points ``e, n`` (any shape, metres)."""
        e, n = np.asarray(e, np.float64), np.asarray(n, np.float64)
        x, y = e - self.origin[0], self.origin[1] - n              # metres from the origin, y south
        fx, fy = x / self.size, y / self.size
        ix, iy = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
        best = np.full(e.shape, np.inf)
        val = np.zeros(e.shape, np.float32)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                cx, cy = (ix + dx) % self.n, (iy + dy) % self.n
                jit = self.jitter[cy, cx]
                d2 = (ix + dx + jit[..., 0] - fx) ** 2 + (iy + dy + jit[..., 1] - fy) ** 2
                closer = d2 < best
                best = np.where(closer, d2, best)
                val = np.where(closer, self.value[cy, cx], val)
        x, y = x.astype(np.float32), y.astype(np.float32)
        out = self.level + self.contrast * val + 2.0 * self.fine(x, y) + 6.0 * self.broad(x, y)
        for dn, grain in self.grain:
            out = out + dn * grain(x, y)
        if self.shade is not None:
            out = out * self.shade.sample(e, n).astype(np.float32)
        return out.astype(np.float32)
