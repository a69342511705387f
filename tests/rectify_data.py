"""Small rectification inputs shared by the io, ops and cli tests: a random image, points
related by a known affine, the CSV files of both."""
import warnings

import numpy as np
import rasterio

CRS = "EPSG:32631"


def _image(path, rows=240, cols=320, seed=0):
    rng = np.random.default_rng(seed)
    img = (rng.random((rows, cols)) * 250 + 1).astype(np.uint8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(path, "w", driver="GTiff", width=cols, height=rows, count=1,
                           dtype="uint8") as ds:
            ds.write(img, 1)
    return img


def _points(n=12, seed=1, rows=240, cols=320):
    rng = np.random.default_rng(seed)
    src = rng.uniform(0, 1, (n, 2)) * [cols, rows]
    dst = src @ np.array([[10.0, 1.0], [1.5, -10.0]]).T + [500000.0, 4600000.0]
    return src, dst


def _apply(geo, col, row):
    return geo.a * col + geo.b * row + geo.c, geo.d * col + geo.e * row + geo.f


def _read(path):
    with rasterio.open(path) as ds:
        return ds.read(1), ds.transform, ds.crs


def _csvs(tmp_path, src, dst, icp=()):
    pts = tmp_path / "pts.csv"
    meas = tmp_path / "meas.csv"
    pts.write_text("id,E,N,H,kind,note\n" + "".join(
        f"G{i},{e:.4f},{n:.4f},10,{'ICP' if i in icp else 'GCP'},x\n" for i, (e, n) in enumerate(dst)))
    meas.write_text("id,view,x,y\n" + "".join(f"G{i},N,{x:.4f},{y:.4f}\n" for i, (x, y) in enumerate(src))
                    + "T1,N,3,4\n" + "".join(f"G{i},F,{x:.4f},{y:.4f}\n" for i, (x, y) in enumerate(src)))
    return pts, meas

