"""The RPC DSM on the real Pléiades triplet (Aubagne, 0.5 m pixels), on a crop of each image:
tie points and the shift-bias fit as the bias benchmark makes them, then the three pairs'
DSM at 1 m. The pairs agree only once the biases are fitted: the raw RPCs are about a pixel
apart across the epipolar lines and put the pairs metres apart in height."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import rasterio

from prismstation.core.models.rpc_adjust import adjust_snooping
from prismstation.core.models.rpc_bias import intersect_points, metres_per_degree
from prismstation.core.matching.rpc_tiepoints import match_tie_points
from prismstation.io.dem import write_dem
from prismstation.io.rpc import read_rpc
from prismstation.core.adjustment.stats import nmad
from prismstation.io.rpc_scene import to_map
from prismstation.ops.rpc_dsm import rpc_dsm
from prismstation.ops.rpc_orient import orient_from_reference
from tests.ops.rpc_synth import write_image

CROP = 320                     # pixels: ~160 m of ground per side
H_SIGMA = 2.0                  # reference heights: the raw intersection + noise, as the bias tests


@pytest.fixture(scope="module")
def crops(tmp_path_factory, shared_data):
    d = tmp_path_factory.mktemp("triplet_crop")
    files = [shared_data / "pleiades_triplet" / f"img_0{i}.tif" for i in (1, 2, 3)]
    full = [read_rpc(f) for f in files]
    lon, lat = full[0].localize(512.0, 512.0, 200.0)
    paths, rpcs, images = [], [], []
    for k, (f, rpc) in enumerate(zip(files, full)):
        x, y = rpc.project(lon, lat, 200.0)
        c0, r0 = int(x) - CROP // 2, int(y) - CROP // 2
        with rasterio.open(f) as ds:
            img = ds.read(1, window=((r0, r0 + CROP), (c0, c0 + CROP))).astype(np.float32)
        write_image(d / f"crop{k}.tif", img)
        paths.append(d / f"crop{k}.tif")
        rpcs.append(rpc.shifted(-c0, -r0))
        images.append(img)
    tp = match_tie_points(images, cell=24)
    before = intersect_points(rpcs, tp.point, tp.image, tp.xy, tp.sigma, tp.n_points)
    href = before.h + np.random.default_rng(0).normal(0, H_SIGMA, tp.n_points)
    fit, kept = adjust_snooping(rpcs, tp.point, tp.image, tp.xy, tp.sigma, bias="shift",
                                height_point=np.arange(tp.n_points), height=href, height_sigma=H_SIGMA)
    return paths, rpcs, fit, kept


def test_real_triplet_dsm(crops):
    paths, rpcs, fit, kept = crops
    crs = "EPSG:32631"
    ground = (fit.lon, fit.lat, fit.h)             # the points kept by the fit
    # a-priori: the RPCs' own height domain, narrowed per tile by the tie points' heights
    dsm, pairs = rpc_dsm(paths, fit.models, posting=1.0, points=ground, crs=crs)
    assert dsm.valid_fraction > 0.9
    agree = dsm.info["pair_agreement"]
    for v in agree.values():
        assert abs(v["median_m"]) < 0.6 and v["nmad_m"] < 2.0, agree
        assert 0.5 < v["nmad_in_sigma"] < 1.6, agree
    assert dsm.info["epipolar_error_px"] < 0.01
    # the tie points' heights lie on the DSM (urban relief: a metre or two of scatter)
    e, n = to_map(crs)(fit.lon, fit.lat)
    points = (np.asarray(e), np.asarray(n), fit.h)
    a, _, c, _, ee, f = dsm.transform
    col = ((points[0] - c) / a).astype(int)
    row = ((points[1] - f) / ee).astype(int)
    inside = (col >= 0) & (col < dsm.heights.shape[1]) & (row >= 0) & (row < dsm.heights.shape[0])
    dh = dsm.heights[row[inside], col[inside]] - points[2][inside]
    assert abs(np.nanmedian(dh)) < 1.0 and nmad(dh) < 2.0
    # the raw RPCs: the widest pair against a narrow one, metres apart
    raw, _ = rpc_dsm(paths, rpcs, pairs=[(0, 1), (1, 2)], posting=1.0, points=ground, crs=crs)
    assert abs(raw.info["pair_agreement"]["(0, 1)-(1, 2)"]["median_m"]) > 2.0


def test_real_triplet_orientation_from_its_own_dsm(crops, tmp_path):
    """No SRTM among the samples covers Aubagne: the reference is the crop's own fitted DSM,
    and the block is moved by a known ground shift through the RPCs' ground offsets."""
    paths, rpcs, fit, kept = crops
    crs = "EPSG:32631"
    ground = (fit.lon, fit.lat, fit.h)
    dsm, _ = rpc_dsm(paths, fit.models, posting=1.0, points=ground, crs=crs)
    write_dem(tmp_path / "ref.tif", dsm.heights, dsm.crs, dsm.transform)
    shift = np.array([5.0, -3.0, 2.0])
    ke, kn = metres_per_degree(float(np.mean(fit.lat)))
    moved = [replace(m, rpc=replace(m.rpc, lon_off=m.rpc.lon_off - shift[0] / ke,
                                    lat_off=m.rpc.lat_off - shift[1] / kn, h_off=m.rpc.h_off - shift[2]))
             for m in fit.models]
    mdsm, _ = rpc_dsm(paths, moved, posting=1.0, pairs=[(0, 2)], crs=crs,
                      points=(fit.lon - shift[0] / ke, fit.lat - shift[1] / kn, fit.h - shift[2]))
    o = orient_from_reference(moved, mdsm.heights, mdsm.transform, mdsm.crs, tmp_path / "ref.tif", cell_m=4.0)
    assert o, o.coreg.reason
    # within 4 σ (+ 0.1 m: the formal σ of a DSM laid on itself is optimistic; found
    # 1.1–1.8 σ off on this crop)
    err = np.abs(np.array(o.shift_m) - shift)
    assert np.all(err < 4 * np.array(o.sigma_m) + 0.1), (o.shift_m, o.sigma_m)
    # each image back on its fitted model within a few tenths of a pixel (it was 11 px off)
    for m_true, m_new in zip(fit.models, o.models):
        x0, y0 = m_true.project(fit.lon, fit.lat, fit.h)
        x1, y1 = m_new.project(fit.lon, fit.lat, fit.h)
        assert np.hypot(x1 - x0, y1 - y0).max() < 0.4
