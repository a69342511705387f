"""The ortho of a real Pléiades image with its RPCs and no bias against GDAL's own RPC geometry on
the same DEM: the positions against GDAL's RPC transformer (exact, ``RPC_DEM``), the image
against ``rasterio.warp.reproject`` with ``rpcs=`` and ``RPC_DEM`` (GDAL's warper, which
interpolates its transformer to 0.125 px)."""
from __future__ import annotations

import numpy as np
import pytest
import rasterio
from pyproj import Transformer
from rasterio.transform import RPCTransformer
from rasterio.warp import Resampling, reproject

from prismstation.cli import main
from prismstation.core.surfaces.ortho import resample
from prismstation.io.dem import write_dem
from prismstation.io.project import load_project
from prismstation.ops.fit import solve_project
from prismstation.ops.ortho_tiles import Heights
from prismstation.core.surfaces import ortho


@pytest.fixture(scope="module")
def block(shared_data, tmp_path_factory):
    d = tmp_path_factory.mktemp("pleiades_ortho")
    images = [shared_data / "pleiades_triplet" / f"img_0{i}.tif" for i in (1, 2, 3)]
    assert main(["new", str(d / "b.prismproj"), "--images", *map(str, images), "--no-ties"]) == 0
    p = load_project(d / "b.prismproj")
    en = p.scene.views["img_01"].footprint(250.0)
    x0, y0 = en.min(axis=0) - 300
    x1, y1 = en.max(axis=0) + 300
    g = 2.0
    E, N = np.meshgrid(np.arange(x0, x1, g) + g / 2, np.arange(y1, y0, -g) - g / 2)
    # a surface with the relief of the place (80–320 m) and slopes up to ~30 %
    h = 200.0 + 60.0 * np.sin((E - x0) / 90.0) * np.cos((N - y0) / 140.0) + 0.02 * (E - x0)
    write_dem(d / "dem.tif", h, p.scene.crs, (g, 0.0, x0, 0.0, -g, y1))
    assert main(["ortho", str(d / "b.prismproj"), "-o", str(d / "o.tif"), "--view", "img_01", "--dem",
                 str(d / "dem.tif"), "--dem-heights", "ellipsoidal", "--bias", "none"]) == 0
    return d, images[0], p


def test_positions_are_gdals_rpc_geometry_on_the_dem(block):
    d, image, p = block
    with rasterio.open(d / "o.tif") as o:
        T, shape, crs = o.transform, (o.height, o.width), o.crs
    sol = solve_project(p)                           # no GCP, no tie: every bias none
    h = Heights(p.scene.crs, "ellipsoidal", str(d / "dem.tif")).on_grid(tuple(T)[:6], shape)
    lat = ortho.fit_lattice(lambda en, hh: sol.model.ground_to_image("img_01", en, hh), tuple(T)[:6], shape,
                            float(np.nanmin(h)), float(np.nanmax(h)))
    mx, my = ortho.positions(lat, h)
    rows, cols = np.mgrid[0:shape[0]:9, 0:shape[1]:9]
    E, N = T.c + T.a * (cols + 0.5), T.f + T.e * (rows + 0.5)
    lon, lat_ = Transformer.from_crs(crs.to_wkt(), "EPSG:4326", always_xy=True).transform(E, N)
    with rasterio.open(image) as src, RPCTransformer(src.rpcs, RPC_DEM=str(d / "dem.tif")) as rt:
        r, c = rt.rowcol(lon.ravel(), lat_.ravel(), op=lambda v: v)
    ours = np.column_stack([(mx + 0.5)[rows, cols].ravel(), (my + 0.5)[rows, cols].ravel()])
    err = np.hypot(ours[:, 0] - np.asarray(c), ours[:, 1] - np.asarray(r))
    inside = (np.asarray(c) > 0) & (np.asarray(c) < 1024) & (np.asarray(r) > 0) & (np.asarray(r) < 1024)
    assert inside.sum() > 5000 and np.nanmax(err[inside]) < ortho.TOLERANCE_PX


def test_the_image_is_gdals_warp_on_the_same_dem(block):
    d, image, p = block
    with rasterio.open(d / "o.tif") as o:
        T, shape, crs = o.transform, (o.height, o.width), o.crs
        ours, valid = o.read(1).astype(np.float32), o.read_masks(1) > 0
    with rasterio.open(image) as src:
        gdal = np.full(shape, np.nan, np.float32)
        reproject(src.read(1).astype(np.float32), gdal, rpcs=src.rpcs, src_crs="EPSG:4326", dst_crs=crs,
                  dst_transform=T, src_nodata=np.nan, dst_nodata=np.nan, resampling=Resampling.bilinear,
                  RPC_DEM=str(d / "dem.tif"))
    both = valid & np.isfinite(gdal)
    assert both.sum() > 0.95 * valid.sum()
    # where GDAL's interpolated transformer stays close the values are the same to the DN
    diff = np.abs(ours - np.rint(gdal))[both]
    assert np.median(diff) <= 1.0
    # the shift between the two over the middle: least squares on the gradient, GDAL's image
    # resampled by cubic convolution (which moves nothing)
    r0, c0, n = shape[0] // 2 - 200, shape[1] // 2 - 200, 400
    yy, xx = np.mgrid[r0:r0 + n, c0:c0 + n].astype(np.float32)
    s = np.zeros(2)
    ref = ours[r0:r0 + n, c0:c0 + n]
    for _ in range(5):
        g = resample(gdal, xx + np.float32(s[0]), yy + np.float32(s[1]), "cubic")
        gy, gx = np.gradient(g)
        ok = np.isfinite(g) & np.isfinite(gx) & np.isfinite(gy) & valid[r0:r0 + n, c0:c0 + n]
        A = np.column_stack([gx[ok], gy[ok], np.ones(ok.sum())])
        s += np.linalg.lstsq(A, (ref - g)[ok], rcond=None)[0][:2]
    assert np.abs(s).max() <= 0.05
