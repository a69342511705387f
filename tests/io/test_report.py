"""The report model (io/report.py): header from a real product's scene file, known coordinates
beside residuals, WGS 84 positions, CSV decimals by unit, NaN-free JSON, the terminal text."""
from __future__ import annotations

import csv
import io
import json
import re
from datetime import datetime, timezone

import numpy as np
import pytest
from pyproj import Transformer

from prismstation.core.models.solution import solve
from prismstation.io import report as rp
from prismstation.io.text_report import format_report
from prismstation.sim.model_triplet import make_points, make_scene


@pytest.fixture(scope="module")
def fitted():
    sc = make_scene()
    pts = make_points(sc, n_gcp=9, n_icp=12, noise_px=0.3, seed=4)
    return sc, pts, solve(sc, pts)


def test_identity_of_a_jaxa_product(tmp_path):
    """Scene and product ids, level, times and source as a CEOS product's scene.json has them."""
    from prismstation.io.products import write_scene_for_product
    from prismstation.io.scene import read_scene
    from tests.io.formats.fixtures import ceos_builder as cb
    truth = cb.build_triplet(tmp_path / "product", one_folder=True)
    scene_path = write_scene_for_product(tmp_path / "product", tmp_path / "proj")
    scene = read_scene(scene_path)
    ident = rp.scene_identity(scene, scene_path)
    assert ident["scene_ids"] == {v: t.scene_id for v, t in truth.items()}
    assert ident["product_ids"] == {v: t.product_id for v, t in truth.items()} == \
        {v: f"O1B2R_U{v}" for v in "NFB"}
    assert ident["scene_id"] == truth["N"].scene_id and ident["product_level"] == "1B2R"
    assert ident["acquired"]["F"].startswith("2007-03-21T11:18:25")
    assert ident["source"] == "JAXA CEOS 1B2"
    # without the file only what the Scene kept: the scene id, no per-view ids
    kept = rp.scene_identity(scene, tmp_path / "gone.json")
    assert kept["scene_id"] == truth["N"].scene_id and kept["product_ids"] == {}


def test_header_operator_date_version(fitted, monkeypatch):
    from prismstation import __version__
    sc = fitted[0]
    when = datetime(2026, 3, 4, 5, 6, 7, 890, tzinfo=timezone.utc)
    h = rp.report_header(sc, operator="  M. Mapper ", created=when, project_path="x.prismproj")
    assert (h["operator"], h["created"], h["software"], h["project"]) == \
        ("M. Mapper", "2026-03-04T05:06:07Z", f"prismstation {__version__}", "x.prismproj")
    assert h["scene_id"] is None and h["product_ids"] == {} and h["orientation"] == "GCP"
    monkeypatch.setattr(rp.getpass, "getuser", lambda: "login7")
    assert rp.report_header(sc, operator=" ")["operator"] == "login7"

    def no_user():
        raise OSError("no user")
    monkeypatch.setattr(rp.getpass, "getuser", no_user)
    assert rp.default_operator() == "unknown"


def test_known_coordinates_beside_residuals(fitted):
    """Without a project the known coordinates are estimate − residual: the points' own ground."""
    sc, pts, sol = fitted
    rep = rp.report_dict(sol)
    truth = {p.id: p.ground for p in pts if p.ground is not None}
    got = {p["id"]: (p["E_known"], p["N_known"], p["h_known"]) for p in rep["points"] if "E_known" in p}
    assert set(got) == set(truth)
    for pid, g in got.items():
        assert g == pytest.approx(truth[pid], abs=1e-6)
    # given by the project: taken as given, H and its kind kept
    known = {pid: {"E": 1.0, "N": 2.0, "h": 3.0, "H": -52.0, "height_kind": "orthometric"} for pid in truth}
    p = rp.report_dict(sol, known=known)["points"][0]
    assert (p["E_known"], p["h_known"], p["H_given"], p["height_kind"]) == (1.0, 3.0, -52.0, "orthometric")


def test_wgs84_positions(fitted):
    # on the central meridian of UTM 29N (−9°), at the equator: independent of any library
    assert rp._lonlat("EPSG:32629", np.array([[500000.0, 0.0]]))[0] == pytest.approx([-9.0, 0.0], abs=1e-9)
    rep = rp.report_dict(fitted[2])
    back = Transformer.from_crs("EPSG:4326", "EPSG:32629", always_xy=True)
    for p in rep["points"]:
        e, n = back.transform(p["lon_est"], p["lat_est"])
        assert (e, n) == pytest.approx((p["E_est"], p["N_est"]), abs=1e-4)


def test_csv_decimals_by_unit(fitted, tmp_path):
    rep = rp.report_dict(fitted[2])
    out = tmp_path / "r.csv"
    rp.write_report(rep, out)
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert len(rows) == sum(len(p["measured"]) for p in rep["points"])
    decimals = {"x": 3, "vy_px": 3, "parallax_px": 3, "E_known": 3, "N_est": 3, "dh": 3,
                "lat_est": 8, "lon_est": 8, "std_residual": 2}
    for row in rows:
        for col, nd in decimals.items():
            if row[col]:
                assert re.fullmatch(rf"-?\d+\.\d{{{nd}}}", row[col]), (col, row[col])
        assert row["blunder"] in ("yes", "no")
    by_id = {p["id"]: p for p in rep["points"]}
    r0 = rows[0]
    p = by_id[r0["id"]]
    assert float(r0["lat_est"]) == pytest.approx(p["lat_est"], abs=5e-9)
    assert float(r0["vx_px"]) == pytest.approx(p["residual_px"][r0["view"]][0], abs=5e-4)
    assert float(r0["E_known"]) == pytest.approx(p["E_known"], abs=5e-4)


def test_json_is_nan_free_and_bad_extension_named(fitted, tmp_path):
    from prismstation.errors import InputError
    sc = fitted[0]
    rep = rp.report_dict(solve(sc, []))      # nothing measured: every statistic undefined
    rp.write_report(rep, tmp_path / "e.json")

    def refuse(token):
        raise AssertionError(f"{token} in the JSON")
    json.loads((tmp_path / "e.json").read_text(), parse_constant=refuse)
    with pytest.raises(InputError, match="unknown report format '.txt'"):
        rp.write_report(rep, tmp_path / "r.txt")


def test_terminal_text_has_the_header(fitted):
    h = rp.report_header(fitted[0], operator="T. Ester",
                         created=datetime(2026, 1, 2, 3, 4, 5, tzinfo=timezone.utc))
    text = format_report(rp.report_dict(fitted[2], header=h))
    assert "2026-01-02 03:04:05 UTC  operator T. Ester" in text
    assert "Table 1. Image residuals" in text and "Table 4. Ground residuals" in text
    assert not re.search(r"seed|paper", text, re.I)
