"""The ``rectify`` command: table, JSON and image; bad input exits 2."""
import json

import numpy as np
import pytest
import rasterio

from prismstation.cli import main
from prismstation.core.models.rectify import compare_transforms
from tests.rectify_data import CRS, _apply, _csvs, _image, _points, _read


def test_rectify_command_table_json_and_image(tmp_path, capsys):
    _image(tmp_path / "img.tif")
    rng = np.random.default_rng(4)
    src, dst = _points(n=16)
    dst = dst + rng.normal(0, 2.0, dst.shape)
    pts, meas = _csvs(tmp_path, src, dst, icp=(0, 7, 11))
    rc = main(["rectify", str(tmp_path / "img.tif"), str(pts), "--measurements", str(meas),
               "--view", "N", "--transform", "projective", "-o", str(tmp_path / "o.tif"),
               "--points-crs", CRS, "--resolution", "8", "--json", str(tmp_path / "r.json")])
    assert rc == 0
    text = capsys.readouterr().out
    icp = np.zeros(16, bool)
    icp[[0, 7, 11]] = True
    reports = compare_transforms(np.round(src, 4), np.round(dst, 4), icp)
    for r in reports:
        assert r.kind in text and f"{r.rmse_gcp:.3f}" in text and f"{r.rmse_icp:.3f}" in text
    d = json.loads((tmp_path / "r.json").read_text())
    assert d["chosen"] == "projective"
    assert [t["rmse_icp_m"] for t in d["transforms"]] == pytest.approx([r.rmse_icp for r in reports])
    out, geo, crs = _read(tmp_path / "o.tif")
    assert geo.a == 8.0 and crs.to_epsg() == 32631 and out.any()


@pytest.mark.parametrize("content,where", [
    ("id,E,N\nA,1,2\nB,1,oops\n", "line 3"),
    ("id,E\nA,1\n", "line 1"),
    ("id,E,N,kind\nA,1,2,TIE\n", "line 2"),
    ("id,E,N\nA,1,2\nA,3,4\n", "line 3"),
])
def test_rectify_command_bad_points_exit_2(tmp_path, capsys, content, where):
    _image(tmp_path / "img.tif")
    pts = tmp_path / "bad.csv"
    pts.write_text(content)
    meas = tmp_path / "m.csv"
    meas.write_text("id,view,x,y\nA,N,1,2\n")
    rc = main(["rectify", str(tmp_path / "img.tif"), str(pts), "--measurements", str(meas),
               "-o", str(tmp_path / "x.tif"), "--points-crs", CRS])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "bad.csv" in err and where in err


def test_rectify_command_too_few_points_and_missing_image(tmp_path, capsys):
    _image(tmp_path / "img.tif")
    src, dst = _points(n=4)
    pts, meas = _csvs(tmp_path, src, dst)
    rc = main(["rectify", str(tmp_path / "img.tif"), str(pts), "--measurements", str(meas),
               "--view", "N", "--transform", "poly2", "-o", str(tmp_path / "x.tif"),
               "--points-crs", CRS])
    cap = capsys.readouterr()
    assert rc == 2 and "at least 6" in cap.err and len(cap.err.strip().splitlines()) == 1
    rc = main(["rectify", str(tmp_path / "nope.tif"), str(pts), "--measurements", str(meas),
               "-o", str(tmp_path / "x.tif")])
    assert rc == 2 and "nope.tif" in capsys.readouterr().err


def test_rectify_command_on_a_georeferenced_real_raster_reproduces_it(shared_data, tmp_path, capsys):
    """GCPs from the SRTM UTM tile's own geotransform: the affine rectification at the same
    resolution (CRS taken from the image) gives back the tile cell for cell."""
    path = shared_data / "srtm" / "N44E005_UTM.tif"
    with rasterio.open(path) as ds:
        geo, data, shape = ds.transform, ds.read(1), ds.shape
    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 1, (8, 2)) * [shape[1], shape[0]]
    e, n = _apply(geo, xy[:, 0], xy[:, 1])
    pts = tmp_path / "p.csv"
    pts.write_text("id,E,N,x,y\n" + "".join(f"P{i},{float(a)!r},{float(b)!r},{float(x)!r},{float(y)!r}\n"
                                            for i, (a, b, (x, y)) in enumerate(zip(e, n, xy))))
    rc = main(["rectify", str(path), str(pts), "--transform", "affine", "-o", str(tmp_path / "o.tif"),
               "--resolution", "90", "--resampling", "nearest"])
    assert rc == 0 and "affine" in capsys.readouterr().out
    out, ogeo, crs = _read(tmp_path / "o.tif")
    assert crs.to_epsg() == 32631
    # the output grid is snapped to multiples of 90 m: output cell centres fall at a fixed
    # fraction of an input cell, and nearest resampling picks input cell (i + r0, j + c0)
    dc, dr = (ogeo.c - geo.c) / 90.0, (geo.f - ogeo.f) / 90.0
    assert ogeo.c % 90 == pytest.approx(0, abs=1e-6) or ogeo.c % 90 == pytest.approx(90)
    c0, r0 = int(np.floor(dc + 0.5)), int(np.floor(dr + 0.5))
    # output cell (i, j) is input cell (i + r0, j + c0)
    h = min(out.shape[0], shape[0] - r0) - max(0, -r0)
    w = min(out.shape[1], shape[1] - c0) - max(0, -c0)
    a = out[max(0, -r0):max(0, -r0) + h, max(0, -c0):max(0, -c0) + w]
    b = data[max(0, r0):max(0, r0) + h, max(0, c0):max(0, c0) + w]
    valid = (a != 0) & (b != 0)
    assert valid.mean() > 0.8 and np.array_equal(a[valid], b[valid])

