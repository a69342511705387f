"""CSV formula injection: an id a spreadsheet would run (``=cmd|' /C calc'!A0``, ``+…``,
``-…``, ``@…``) is written as text (a leading ``'``) by every CSV writer and read back as it
was by prismstation's own readers; numbers — negative ones too — stay numbers."""
from __future__ import annotations

import csv
import json

import pytest

from prismstation.io.csvtable import text_cell
from prismstation.io.pointfiles import read_point_file, write_point_file
from prismstation.io.points import read_ground_points, read_measurements
from tests.robustness import faults as ft

HOSTILE = ["=cmd|' /C calc'!A0", "+1+cmd|' /C calc'!A0", "-2+3", "@SUM(A1:A9)", "=HYPERLINK(\"x\")"]


def _formula_cells(path) -> list[str]:
    """Cells of the CSV at ``path`` a spreadsheet would take for a formula."""
    bad = []
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.reader(line for line in fh if not line.startswith("#")):
            for c in row:
                if c[:1] in ("=", "+", "-", "@", "\t", "\r"):
                    try:
                        float(c)
                    except ValueError:
                        bad.append(c)
    return bad


@pytest.fixture()
def hostile(sim):
    """The sim project with its first points renamed to hostile ids."""
    path = sim / "p.prismproj"
    doc = json.loads(path.read_text())
    names = {p["id"]: h for p, h in zip([p for p in doc["points"] if p["kind"] != "TIE"], HOSTILE)}
    for p in doc["points"] + doc["measurements"]:
        p["id"] = names.get(p["id"], p["id"])
    path.write_text(json.dumps(doc))
    return path


def test_text_cell():
    assert text_cell("=1+2") == "'=1+2" and text_cell("@x") == "'@x" and text_cell("\tx") == "'\tx"
    assert text_cell("-12.5") == "-12.5" and text_cell("+3") == "+3" and text_cell("P1") == "P1"
    assert text_cell("-1e-3") == "-1e-3" and text_cell("-x") == "'-x"


def test_the_report_csv(hostile, tmp_path):
    out = tmp_path / "r.csv"
    rc, _, err = ft.run_cli(["report", hostile, "-o", out])
    assert rc == 0, err
    assert _formula_cells(out) == []
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    ids = {r["id"] for r in rows}
    assert {"'" + h for h in HOSTILE if not h.startswith("-2")} <= ids
    assert "'-2+3" in ids
    assert any(r["dE"].startswith("-") for r in rows)   # negative numbers stay numbers
    float(next(r["dE"] for r in rows if r["dE"].startswith("-")))


@pytest.mark.parametrize("suffix", [".csv", ".points"])
def test_point_files_are_read_back_as_written(hostile, tmp_path, suffix):
    from prismstation.io.georef import PointFile
    from prismstation.io.project import load_project
    project = load_project(hostile)
    pf = PointFile(tuple(p for p in project.points.values() if p.kind != "TIE"), tuple(m for m in project.measurements.values()
                                                         if m.view == "N"), project.scene.crs, None, None)
    out = tmp_path / f"p{suffix}"
    write_point_file(pf, out, view="N")
    assert _formula_cells(out) == []
    back = read_point_file(out, height="ellipsoidal")
    assert set(HOSTILE) <= {p.id for p in back.points}


def test_the_ground_and_measurement_csvs(hostile, tmp_path):
    from prismstation.io.pointfiles import read_ground_csv
    g, m = tmp_path / "g.csv", tmp_path / "m.csv"
    (tmp_path / "in.csv").write_text(ft_points(hostile))
    rc, _, err = ft.run_cli(["points", tmp_path / "in.csv", "-o", g])
    assert rc == 0, err
    assert _formula_cells(g) == []
    assert set(HOSTILE) <= {p.id for p in read_ground_points(g)}
    assert set(HOSTILE) <= {p.id for p in read_ground_csv(g).points}
    from prismstation.io.points import measurements_csv
    from prismstation.io.project import load_project
    m.write_text(measurements_csv(load_project(hostile).measurements.values()))
    assert _formula_cells(m) == []
    assert set(HOSTILE) <= {x.id for x in read_measurements(m)}


def ft_points(project_path) -> str:
    from prismstation.io.points import ground_points_csv
    from prismstation.io.project import load_project
    return ground_points_csv([p for p in load_project(project_path).points.values() if p.kind != "TIE"])
