"""The RPC DSM on the real Pléiades triplet (Aubagne, 0.5 m pixels), on a crop of each image:
tie points and the shift-bias fit as the bias benchmark makes them, then the three pairs'
DSM at 1 m. The pairs agree only once the biases are fitted: the raw RPCs are about a pixel
apart across the epipolar lines and put the pairs metres apart in height."""
from __future__ import annotations

import numpy as np
import pytest
import rasterio

from prismstation.core.rpc_adjust import adjust_snooping
from prismstation.core.rpc_bias import intersect_points
from prismstation.core.rpc_tiepoints import match_tie_points
from prismstation.io.rpc import read_rpc
from prismstation.core.stats import nmad
from prismstation.ops.rpc_dsm import rpc_dsm, to_map
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
