"""Small inputs for the hostile-file tests: images with RPCs (a plain GeoTIFF and a ``.RPB``
beside it, no shared data needed)."""
from __future__ import annotations

from pathlib import Path

from tests.io.test_rpc import plain_tif, write_rpb
from tests.ops.rpc_synth import make_rpc


def rpc_images(folder: Path, n: int = 3, size: int = 64) -> list[Path]:
    """``n`` images ``img_01.tif``… of ``size`` px with RPCs over the same ground."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for i in range(1, n + 1):
        img = folder / f"img_{i:02d}.tif"
        plain_tif(img, size)
        write_rpb(make_rpc(5.55, 43.29, size=size, tan_along=0.2 * (i - 2), seed=i), img.with_suffix(".RPB"))
        out.append(img)
    return out
