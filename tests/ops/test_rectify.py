"""Single-image rectification into a GeoTIFF (ops.rectify): inverse mapping, GDAL agreement,
output CRS, progress and cancel, the lattice inverse map, a real Pléiades crop."""
import warnings

import numpy as np
import pytest
import rasterio

from prismstation.core.models.rectify import compare_transforms, fit_transform
from prismstation.errors import Cancelled
from prismstation.ops.rectify import rectify_raster
from tests.rectify_data import CRS, _apply, _image, _points, _read


@pytest.mark.parametrize("kind", ["affine", "projective", "poly2"])
def test_nearest_rectification_is_the_inverse_mapping(tmp_path, kind):
    img = _image(tmp_path / "img.tif")
    src, dst = _points()
    t = fit_transform(kind, src, dst)
    res = rectify_raster(tmp_path / "img.tif", t, tmp_path / "out.tif", points_crs=CRS,
                         resolution=7.0, block=100, resampling="nearest")
    out, geo, crs = _read(tmp_path / "out.tif")
    assert crs.to_epsg() == 32631 and geo.a == 7.0 and out.shape == (res.height, res.width)
    rows, cols = np.mgrid[0:out.shape[0], 0:out.shape[1]]
    e, n = _apply(geo, cols.ravel() + 0.5, rows.ravel() + 0.5)
    xy = t.inverse(np.column_stack([e, n]))
    inside = np.all((xy > 0.01) & (xy < [319.99, 239.99]), axis=1)
    expect = img[xy[inside, 1].astype(int), xy[inside, 0].astype(int)]
    assert np.mean(out.ravel()[inside] == expect) > 0.999
    outside = np.any((xy < -0.01) | (xy > [320.01, 240.01]), axis=1)
    assert np.all(out.ravel()[outside] == 0)
    # the footprint of the image lies inside the output grid
    corners = t(np.array([[0, 0], [320, 0], [0, 240], [320, 240]]))
    left, top = geo.c, geo.f
    assert np.all(corners[:, 0] >= left) and np.all(corners[:, 0] <= left + 7 * res.width)
    assert np.all(corners[:, 1] <= top) and np.all(corners[:, 1] >= top - 7 * res.height)


def test_rectification_agrees_with_gdal_gcp_warp(tmp_path):
    """Exact affine data: GDAL's order-1 GCP warp (rasterio.warp.reproject) is the same map."""
    from rasterio.control import GroundControlPoint
    from rasterio.enums import Resampling
    from rasterio.warp import reproject

    img = _image(tmp_path / "img.tif")
    src, dst = _points(n=5)
    t = fit_transform("affine", src, dst)
    rectify_raster(tmp_path / "img.tif", t, tmp_path / "out.tif", points_crs=CRS, resolution=6.0,
                   resampling="nearest")
    ours, geo, _ = _read(tmp_path / "out.tif")
    gcps = [GroundControlPoint(row=y, col=x, x=X, y=Y) for (x, y), (X, Y) in zip(src, dst)]
    ref = np.zeros_like(ours)
    reproject(img, ref, gcps=gcps, src_crs=CRS, dst_transform=geo, dst_crs=CRS,
              resampling=Resampling.nearest, src_nodata=0, dst_nodata=0)
    both = (ours > 0) & (ref > 0)
    assert both.sum() > 0.9 * max((ours > 0).sum(), (ref > 0).sum())
    assert np.mean(ours[both] == ref[both]) > 0.995


def test_output_crs_and_bilinear(tmp_path):
    rows, cols = np.mgrid[0:240, 0:320]
    img = (rows + cols).astype(np.uint16)     # a plane: bilinear reproduces it exactly
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(tmp_path / "ramp.tif", "w", driver="GTiff", width=320, height=240,
                           count=1, dtype="uint16") as ds:
            ds.write(img, 1)
    src, dst = _points()
    t = fit_transform("affine", src, dst)
    res = rectify_raster(tmp_path / "ramp.tif", t, tmp_path / "geo.tif", points_crs=CRS,
                         out_crs="EPSG:4326")
    out, geo, crs = _read(tmp_path / "geo.tif")
    assert crs.to_epsg() == 4326 and 1e-5 < res.resolution < 1e-3
    from pyproj import Transformer
    tr = Transformer.from_crs("EPSG:4326", CRS, always_xy=True)
    r, c = np.mgrid[5:out.shape[0]:17, 5:out.shape[1]:13]
    lon, lat = _apply(geo, c.ravel() + 0.5, r.ravel() + 0.5)
    xy = t.inverse(np.column_stack(tr.transform(lon, lat)))
    ok = np.all((xy > 1) & (xy < [319, 239]), axis=1)
    expect = (xy[ok, 0] - 0.5) + (xy[ok, 1] - 0.5)
    assert ok.sum() > 50
    assert np.abs(out[r.ravel()[ok], c.ravel()[ok]] - expect).max() <= 0.51


def test_progress_reports_and_cancels(tmp_path):
    _image(tmp_path / "img.tif")
    src, dst = _points()
    t = fit_transform("affine", src, dst)
    seen = []
    rectify_raster(tmp_path / "img.tif", t, tmp_path / "a.tif", points_crs=CRS, resolution=5,
                   block=64, progress=lambda f, m="": seen.append(f) or True)
    assert len(seen) > 4 and seen[-1] == 1.0 and seen == sorted(seen)
    with pytest.raises(Cancelled):
        rectify_raster(tmp_path / "img.tif", t, tmp_path / "b.tif", points_crs=CRS, resolution=5,
                       block=64, progress=lambda f, m="": f < 0.3)
    assert not (tmp_path / "b.tif").exists()
    before = (tmp_path / "a.tif").read_bytes()
    with pytest.raises(Cancelled):                  # a cancelled run leaves an existing file alone
        rectify_raster(tmp_path / "img.tif", t, tmp_path / "a.tif", points_crs=CRS, resolution=5,
                       block=64, progress=lambda f, m="": f < 0.3)
    assert (tmp_path / "a.tif").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix != "" and p.name != "settings") == \
        ["a.tif", "img.tif"]


@pytest.mark.parametrize("kind", ["projective", "poly3"])
def test_lattice_inverse_map_matches_exact(kind):
    from prismstation.ops.rectify import _inverse_map

    rng = np.random.default_rng(5)
    src = rng.uniform(0, 4000, (20, 2))
    dst = src @ np.array([[2.5, 0.3], [0.2, -2.5]]).T + [5e5, 4.6e6] + 3e-5 * src ** 2
    t = fit_transform(kind, src, dst)

    def exact(rr, cc):
        xy = t.inverse(np.column_stack([5e5 + 2000 + 7.0 * np.ravel(cc), 4.6e6 - 3000 - 7.0 * np.ravel(rr)]))
        return xy[:, 0].reshape(np.shape(rr)), xy[:, 1].reshape(np.shape(rr))

    x, y = _inverse_map(exact, 300, 200)
    R, C = np.mgrid[0:300, 0:200]
    xe, ye = exact(R, C)
    assert np.nanmax(np.hypot(x - xe, y - ye)) < 0.05
    assert np.array_equal(np.isnan(x), np.isnan(xe))


def test_real_pleiades_crop_against_gdal_rpc_warp(shared_data, tmp_path):
    """Real uint16 crop with RPCs: GCPs from the RPC model at one height, our projective
    rectification vs GDAL's RPC warp (rasterio.warp.reproject) onto the same UTM grid."""
    from pyproj import Transformer
    from rasterio.enums import Resampling
    from rasterio.transform import RPCTransformer
    from rasterio.warp import reproject

    path = shared_data / "pleiades_triplet" / "img_01.tif"
    with rasterio.open(path) as ds:
        rpcs, img = ds.rpcs, ds.read(1)
    h = 300.0
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 1024, (20, 2))
    with RPCTransformer(rpcs) as t:          # heights passed as zs (RPC_HEIGHT would add to them)
        lon, lat = t.xy(xy[:, 1], xy[:, 0], zs=np.full(20, h), offset="ul")
    en = np.column_stack(Transformer.from_crs(4326, 32631, always_xy=True).transform(lon, lat))
    reports = compare_transforms(xy, en, np.arange(20) >= 14)
    assert all(r.rmse_icp < 0.05 for r in reports if r.ok)     # 0.5 m pixels: < 0.1 px
    t = next(r.transform for r in reports if r.kind == "projective")
    res = rectify_raster(path, t, tmp_path / "rect.tif", points_crs="EPSG:32631", resolution=0.5)
    ours, geo, _ = _read(tmp_path / "rect.tif")
    ref = np.zeros_like(ours)
    reproject(img, ref, rpcs=rpcs, src_crs="EPSG:4326", dst_transform=geo, dst_crs="EPSG:32631",
              resampling=Resampling.bilinear, RPC_HEIGHT=h, src_nodata=0, dst_nodata=0)
    both = (ours > 0) & (ref > 0)
    assert both.sum() > 0.8 * (ours > 0).sum() and res.width * res.height > 1e6
    diff = ours[both].astype(float) - ref[both]
    spread = img.astype(float).std()
    assert abs(diff.mean()) < 0.01 * spread and np.abs(diff).mean() < 0.03 * spread

