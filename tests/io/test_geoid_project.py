import json
import math

import numpy as np
import pyproj
import pytest

from prismstation.errors import InputError
from prismstation.io.geoid import ConstantGeoid, GridGeoid
from prismstation.io.points import read_ground_points, read_measurements
from prismstation.io.project import load_project, save_project
from prismstation.ops.fit import solve_project
from prismstation.model.points import Measurement
from prismstation.sim.model_triplet import make_points, make_scene
from tests.cli.test_fit import write_triplet


def test_grid_geoid_matches_proj(shared_data):
    """Our bilinear sampling of egm96_15.gtx against PROJ's own vertical transformation."""
    grid = shared_data / "geoid" / "egm96_15.gtx"
    g = GridGeoid(grid)
    pyproj.datadir.append_data_dir(str(grid.parent))
    tr = pyproj.Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True, allow_ballpark=False)
    lon = np.array([-8.61, -8.0, 5.27, 179.9, -179.9, 0.1])
    lat = np.array([41.15, 41.2, 44.17, 10.0, -35.0, 51.5])
    _, _, h = tr.transform(lon, lat, np.zeros_like(lon))
    ours = g.undulation(lon, lat, "EPSG:4326")
    assert np.allclose(ours, h, atol=0.02)
    assert ours[0] == pytest.approx(55.58, abs=0.05)  # data README: Porto
    # in a projected CRS: UTM 29N around Porto
    e, n = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32629", always_xy=True).transform(-8.61, 41.15)
    assert g.undulation(np.array([e]), np.array([n]), "EPSG:32629")[0] == pytest.approx(ours[0], abs=1e-6)


def test_missing_grid_is_an_error(tmp_path):
    with pytest.raises(InputError):
        GridGeoid(tmp_path / "nope.gtx")


def test_points_crs_conversion(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("id;E;N;H;kind;note\nA;-8.61;41.15;100;ICP;church\n")
    (p,) = read_ground_points(f, crs="EPSG:4326", to_crs="EPSG:32629", height="orthometric")
    e, n = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32629", always_xy=True).transform(-8.61, 41.15)
    assert (p.E, p.N) == pytest.approx((e, n)) and p.kind == "ICP" and p.height_kind == "orthometric"
    assert p.extra == {"note": "church"}


@pytest.mark.parametrize("content,line,msg", [
    ("id,E,N\nA,1,2\n", 1, "lacks column H"),
    ("id,E,N,H\nA,1,2,3\nA,1,2,3\n", 3, "appears twice"),
    ("id,E,N,H,kind\nA,1,2,3,XYZ\n", 2, "kind"),
    ("id,E,N,H\nA,1,2\n", 2, "fields"),
    ("id,E,N,H\nA,1,nan,3\n", 2, "finite"),
])
def test_points_errors_name_line(tmp_path, content, line, msg):
    f = tmp_path / "bad.csv"
    f.write_text(content)
    with pytest.raises(InputError) as e:
        read_ground_points(f)
    assert e.value.line == line and msg in str(e.value) and "bad.csv" in str(e.value)


def test_measurement_view_checked(tmp_path):
    f = tmp_path / "m.csv"
    f.write_text("id,view,x,y\nA,N,1,2\nA,Q,1,2\n")
    with pytest.raises(InputError, match="line 3.*view 'Q'"):
        read_measurements(f, views=["N", "F", "B"])


def _project(tmp_path):
    from prismstation.ops.project import create
    sc = make_scene()
    write_triplet(tmp_path, sc, make_points(sc, noise_px=0.3), geoid=55.0, ortho=True)
    return create(tmp_path / "p.prismproj", tmp_path / "scene.json", tmp_path / "points.csv",
                  tmp_path / "measurements.csv")


def test_project_roundtrip_and_backup(tmp_path):
    proj = _project(tmp_path)
    path = tmp_path / "p.prismproj"
    proj.set_measurement(Measurement("NEW", "N", 10.5, 20.25))
    save_project(proj, path)
    assert (tmp_path / "p.prismproj.bak").exists()
    again = load_project(path)
    assert again.points == proj.points and again.measurements == proj.measurements
    assert again.points["NEW"].kind == "TIE"
    a, b = solve_project(proj), solve_project(again)
    assert np.allclose(a.bias["N"].params, b.bias["N"].params)
    # orthometric heights went through the 55 m geoid: h residuals stay at the noise level
    assert abs(a.stats["height"]["ICP"].mean) < 2.0


def test_newer_project_refused_untouched(tmp_path):
    _project(tmp_path)
    path = tmp_path / "p.prismproj"
    doc = json.loads(path.read_text())
    doc["format"] = "prismstation-project/7"
    path.write_text(json.dumps(doc))
    before = path.read_bytes()
    with pytest.raises(InputError, match="newer prismstation"):
        load_project(path)
    assert path.read_bytes() == before


def test_malformed_project_names_line(tmp_path):
    _project(tmp_path)
    path = tmp_path / "p.prismproj"
    text = path.read_text().replace('"kind": "ICP"', '"kind": "BOGUS"', 1)
    path.write_text(text)
    with pytest.raises(InputError) as e:
        load_project(path)
    assert e.value.line is not None and "malformed point" in str(e.value)


def test_saved_files_get_normal_permissions(tmp_path):
    import os
    from prismstation.io.jsonfile import write_atomic
    umask = os.umask(0o022)
    try:
        write_atomic(tmp_path / "a.json", "{}")
        assert (tmp_path / "a.json").stat().st_mode & 0o777 == 0o644
        os.chmod(tmp_path / "a.json", 0o640)
        write_atomic(tmp_path / "a.json", "{}")  # a new version keeps the file's mode
        assert (tmp_path / "a.json").stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(umask)
