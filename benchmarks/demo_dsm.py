"""The demo's DSM at 5 m through ``prismstation dsm``, against the demo's true terrain, and its
shaded relief (voids in red) for ``docs/``.

    python benchmarks/demo_dsm.py --out docs/dsm_demo_5m_shaded.jpg

Prints wall and CPU seconds, fill (matched share of the cells all three images see), NMAD,
RMSE and bias of DSM − truth (m); the shaded relief shows seams, if any, as straight lines.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rasterio

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from prismstation.cli import main  # noqa: E402
from prismstation.cli.demo import ensure_demo  # noqa: E402
from prismstation.core.adjustment.stats import nmad  # noqa: E402
from prismstation.io.dem import read_dem  # noqa: E402


def hillshade(h: np.ndarray, posting: float, azimuth=315.0, altitude=45.0) -> np.ndarray:
    """Lambertian shading in [0, 1] of a north-up grid (NaN where ``h`` is)."""
    gy, gx = np.gradient(h, posting)
    slope = np.arctan(np.hypot(gx, gy))
    aspect = np.arctan2(-gx, gy)
    az, alt = np.radians(azimuth), np.radians(altitude)
    return np.clip(np.sin(alt) * np.cos(slope) + np.cos(alt) * np.sin(slope) * np.cos(az - aspect), 0, 1)


def save_jpeg(rgb: np.ndarray, path: Path) -> None:
    from PySide6.QtGui import QImage
    rgb = np.ascontiguousarray(rgb, np.uint8)
    QImage(rgb.data, rgb.shape[1], rgb.shape[0], 3 * rgb.shape[1], QImage.Format.Format_RGB888).save(str(path), quality=90)


def main_demo(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="shaded relief JPEG to write")
    ap.add_argument("--posting", type=float, default=5.0)
    ap.add_argument("--dir", help="the demo's folder (default: the user's demo)")
    a = ap.parse_args(argv)
    project = ensure_demo(a.dir)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "dsm.tif"
        t0, c0 = time.perf_counter(), time.process_time()
        code = main(["dsm", str(project), "-o", str(out), "--posting", str(a.posting)])
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if code not in (0, 3):
            return code
        with rasterio.open(out) as ds:
            h, mask = ds.read(1), ds.read(2)
            crs, t = ds.crs, tuple(ds.transform)[:6]
    seen = np.isfinite(mask)
    truth = read_dem(project.parent / "triplet" / "truth_dem.tif", crs, t, h.shape, resampling="bilinear").heights
    e = (h - truth)[seen & np.isfinite(h)]
    fill = float((mask[seen] == 1).mean())
    print(f"demo DSM at {a.posting:g} m: {h.shape[1]} × {h.shape[0]} cells, {wall:.1f} s wall, {cpu:.1f} s CPU, "
          f"fill {100 * fill:.2f} %, NMAD {nmad(e):.2f} m, "
          f"RMSE {np.sqrt(np.mean(e ** 2)):.2f} m, bias {e.mean():+.2f} m")
    if a.out:
        shade = hillshade(np.where(np.isfinite(h), h, np.nanmedian(h)), a.posting)
        grey = (40 + 200 * shade).astype(np.uint8)
        rgb = np.repeat(grey[..., None], 3, axis=2)
        rgb[seen & ~np.isfinite(h)] = (220, 30, 30)
        rgb[~seen] = (255, 255, 255)
        save_jpeg(rgb, a.out)
        print(f"shaded relief: {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main_demo())
