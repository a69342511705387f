"""``prismstation transfer``: the project's points searched in the views they lack, on another
simulator's 10 km scene (its GCPs measured in N, F and B, its 41 check points in N only; its
SRTM-like reference), against the scene's exact image positions."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.io.project import load_project
from prismstation.ops import transfer_points


@pytest.fixture()
def n_only(foreign_data, tmp_path):
    """The foreign scene's project with its check points measured in N only: ``(project path,
    scene folder, measured N positions)``."""
    return n_only_project(foreign_data / "smooth_hills_10km", tmp_path)


def n_only_project(d, tmp_path):
    """:func:`n_only` of the scene folder ``d``, the project written in ``tmp_path``."""
    from prismstation.ops.project import create
    gcps = {r["id"] for r in csv.DictReader((d / "points.csv").open()) if r["kind"] == "GCP"}
    rows = list(csv.DictReader((d / "measurements.csv").open()))
    kept = [r for r in rows if r["id"] in gcps or r["view"] == "N"]
    m = tmp_path / "m.csv"
    with m.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(kept)
    proj = tmp_path / "f.prismproj"
    create(proj, d / "scene.json", d / "points.csv", m, geoid="auto")
    n = {r["id"]: (float(r["x"]), float(r["y"])) for r in rows if r["view"] == "N"}
    return proj, d, n


def errors_px(rows, d, n) -> np.ndarray:
    """Each transferred measurement's distance (px) to the exact position of the point the
    source's measurement marks (the exact one moved by the N measurement's own offset)."""
    exact = json.loads((d / "truth_image.json").read_text())
    out = []
    for pid, view, x, y in rows:
        off = np.subtract(n[pid], exact[pid]["N"])
        out.append(float(np.hypot(*(np.subtract((x, y), exact[pid][view]) - off))))
    return np.array(out)


def test_transfer_finds_the_check_points_in_f_and_b(n_only, tmp_path, capsys):
    proj, d, n = n_only
    before = proj.read_bytes()
    out_csv = tmp_path / "found.csv"
    out_json = tmp_path / "found.json"
    assert main(["transfer", str(proj), "--dem", str(d / "srtm_like.tif"), "--csv", str(out_csv),
                 "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "transfer: 41 points, through the fit (affine bias); reference DEM" in out
    assert "found: F 41 of 41, B 41 of 41" in out, out
    rows = [(r["id"], r["view"], float(r["x"]), float(r["y"])) for r in csv.DictReader(out_csv.open())]
    assert len(rows) == 82 and {v for _, v, _, _ in rows} == {"F", "B"}
    err = errors_px(rows, d, n)
    assert err.max() < 1.0 and np.sqrt(np.mean(err ** 2)) <= 0.15, np.round(np.sort(err)[-5:], 2)
    assert proj.read_bytes() == before                    # without --save the project is not touched
    # the JSON holds every search, the same positions, a σ and a covariance each, no NaN
    text = out_json.read_text()
    doc = json.loads(text)
    assert "NaN" not in text and doc["summary"] == "found: F 41 of 41, B 41 of 41"
    got = {(p["id"], v): r for p in doc["points"] for v, r in p["views"].items()}
    assert len(got) == 82 and all(r["status"] == "ok" for r in got.values())
    for pid, view, x, y in rows:
        r = got[pid, view]
        assert (r["x"], r["y"]) == (x, y) and 0 < r["sigma_along_px"] < 0.5
        assert np.isclose(np.trace(r["cov_px2"]), r["sigma_along_px"] ** 2 + r["sigma_across_px"] ** 2)


def test_save_adds_the_found_points_and_refits(n_only, capsys):
    proj, d, n = n_only
    assert main(["transfer", str(proj), "--points", "C01", "C02", "--dem", str(d / "srtm_like.tif"),
                 "--save"]) == 0
    out = capsys.readouterr().out
    assert "4 measurements added to" in out and "fit (affine bias): σ0" in out, out
    project = load_project(proj)
    rows = [(pid, v, project.measurement(pid, v).x, project.measurement(pid, v).y)
            for pid in ("C01", "C02") for v in "FB"]
    assert errors_px(rows, d, n).max() < 1.0
    assert project.measurement("C03", "F") is None        # only the points asked for
    # asked again: measured in every view now, nothing to search
    assert main(["transfer", str(proj), "--points", "C01"]) == 0
    assert "nothing to search" in capsys.readouterr().out


def test_an_unknown_point_is_named_and_nothing_written(n_only, capsys):
    proj, _, _ = n_only
    before = proj.read_bytes()
    assert main(["transfer", str(proj), "--points", "C01", "X9", "--save"]) == 2
    err = capsys.readouterr().err
    assert "no point 'X9' in the project" in err and "Traceback" not in err
    assert proj.read_bytes() == before


def test_ctrl_c_writes_nothing(n_only, tmp_path, monkeypatch, capsys):
    proj, _, _ = n_only
    before = proj.read_bytes()

    def interrupted(*args, **kw):
        raise KeyboardInterrupt
    monkeypatch.setattr(transfer_points, "transfer", interrupted)
    out_csv = tmp_path / "found.csv"
    assert main(["transfer", str(proj), "--csv", str(out_csv), "--save"]) == 130
    assert "interrupted: nothing written" in capsys.readouterr().err
    assert proj.read_bytes() == before and not out_csv.exists()


def test_nothing_found_is_exit_3_and_says_why(n_only, monkeypatch, capsys):
    proj, _, _ = n_only
    before = proj.read_bytes()
    monkeypatch.setattr(transfer_points, "transfer", lambda *a, **k: {})     # every view outside
    assert main(["transfer", str(proj), "--points", "C01", "--save"]) == 3
    cap = capsys.readouterr()
    assert "the prediction lies outside the image" in cap.out and "not found: 2 outside" in cap.out
    assert "no point found" in cap.err
    assert proj.read_bytes() == before


def test_the_json_says_why_a_point_was_not_found(n_only, tmp_path, monkeypatch):
    proj, _, _ = n_only
    monkeypatch.setattr(transfer_points, "transfer", lambda *a, **k: {})     # every view outside
    out_json = tmp_path / "r.json"
    assert main(["transfer", str(proj), "--points", "C01", "--json", str(out_json)]) == 3
    doc = json.loads(out_json.read_text())
    assert doc["points"][0]["views"]["F"] == {"status": "outside", "reason": "the prediction lies outside the image"}
