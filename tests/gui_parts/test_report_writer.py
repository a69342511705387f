"""write_document: HTML tables hold the report dict's numbers; the PDF has them too; CLI path."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser

import pytest

from prismstation.io.report import report_dict
from prismstation.gui.report_writer import report_html, write_document


class Tables(HTMLParser):
    """``{table id: [[cell text, ...], ...]}`` and the ``src`` of every image."""

    def __init__(self):
        super().__init__()
        self.tables, self.images = {}, []
        self._id = self._row = self._cell = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._id = a.get("id")
            self.tables[self._id] = []
        elif tag == "tr" and self._id:
            self._row = []
            self.tables[self._id].append(self._row)
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []
        elif tag == "img":
            self.images.append(a.get("src", ""))

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._id = self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def parse(text):
    p = Tables()
    p.feed(text)
    return p


def num(cell):
    return float(cell.replace("+", ""))


@pytest.fixture(scope="module")
def report(fitted):
    return report_dict(fitted[2], project_path="demo.prismproj", geoid="constant 55.0 m")


def check_tables(tables, r):
    st = r["statistics"]
    t1 = {row[0]: row[1:] for row in tables["table1"][1:]}
    m = st["image"]["N"]
    for j, (kind, c) in enumerate((("GCP", "x"), ("GCP", "y"), ("ICP", "x"), ("ICP", "y"))):
        assert int(t1["n"][j]) == m[kind]["m"][c]["n"]
        for label, key in (("Minimum", "min"), ("Maximum", "max"), ("RMS", "rms"), ("Mean", "mean")):
            assert num(t1[label][j]) == pytest.approx(m[kind]["m"][c][key], abs=0.0051)
    assert num(t1["Planimetric RMS"][3]) == pytest.approx(m["ICP"]["m"]["planimetric_rms"], abs=0.0051)
    t2 = {row[0]: row[1:] for row in tables["table2"][1:]}
    assert num(t2["Mean"][0]) == pytest.approx(st["F-N"]["mean"], abs=0.0051)
    assert num(t2["Std. dev."][1]) == pytest.approx(st["B-N"]["std"], abs=0.0051)
    t3 = {row[0]: row[1:] for row in tables["table3"][1:]}
    assert num(t3["RMS"][1]) == pytest.approx(st["height"]["ICP"]["rms"], abs=0.0051)
    assert num(t3["Maximum"][0]) == pytest.approx(st["height"]["GCP"]["max"], abs=0.0051)
    t4 = {row[0]: row[1:] for row in tables["ground"][1:]}
    assert num(t4["RMS"][2]) == pytest.approx(st["ground"]["ICP"]["x"]["rms"], abs=0.0051)
    par = {row[0]: row[1:] for row in tables["parallax"][1:]}
    assert num(par["c1 (m/px)"][0]) == pytest.approx(r["model"]["parallax"]["c1"], abs=5.1e-5)
    bias = {row[0]: row[1:] for row in tables["bias"][1:]}
    b5 = r["model"]["bias"]["N"]["parameters"]["B5"]
    value, std = (float(s) for s in bias["B5"][0].split("±"))
    assert value == pytest.approx(b5["value"], rel=1e-3) and std == pytest.approx(b5["std"], rel=1e-3)
    assert num(bias["σ0 (px)"][0]) == pytest.approx(r["model"]["bias"]["N"]["sigma0"], abs=5.1e-4)
    rows = tables["points"][1:]
    assert [row[0] for row in rows] == [p["id"] for p in r["points"]]
    head = tables["points"][0]
    for row, p in zip(rows, r["points"]):
        cell = dict(zip(head, row))
        assert num(cell["h est"]) == pytest.approx(p["h_est"], abs=0.0051)
        assert num(cell["dh"]) == pytest.approx(p["dh"], abs=0.0051)
        assert num(cell["vx N"]) == pytest.approx(p["residual_px"]["N"][0], abs=0.0051)
        assert (cell["blunder"] == "yes") == p["blunder"]


def test_html_tables_match_the_report(tmp_path, report, qtbot):
    out = tmp_path / "r.html"
    write_document(report, out)
    page = parse(out.read_text(encoding="utf-8"))
    check_tables(page.tables, report)
    assert len(page.images) == 4 and all(s.startswith("data:image/png;base64,") for s in page.images)
    text = out.read_text(encoding="utf-8")
    assert "EPSG:32629" in text and "constant 55.0 m" in text and "demo.prismproj" in text
    blunder_rows = re.findall(r'<tr bgcolor="#ffd6d6"><td[^>]*>([^<]+)</td>', text)
    assert blunder_rows == [p["id"] for p in report["points"] if p["blunder"]] != []


def test_given_figures_are_embedded(qtbot, report):
    from PySide6.QtGui import QImage
    im = QImage(40, 30, QImage.Format.Format_RGB32)
    im.fill(0x123456)
    html = report_html(report, {"height": "fig.png"})
    assert parse(html).images == ["fig.png"]
    with pytest.raises(Exception, match="unknown document format"):
        write_document(report, "x.docx", figures={"height": im})


@pytest.mark.skipif(not all(shutil.which(t) for t in ("pdftotext", "pdftoppm", "pdfimages")),
                    reason="poppler-utils not installed")
def test_pdf_holds_the_numbers_and_pages_render(tmp_path, report, qtbot):
    out = tmp_path / "r.pdf"
    write_document(report, out)
    assert out.read_bytes()[:5] == b"%PDF-"
    text = subprocess.run(["pdftotext", "-layout", str(out), "-"], capture_output=True,
                          text=True, check=True).stdout
    assert "Table 1" in text and "Table 3" in text and "EPSG:32629" in text
    icp = report["statistics"]["image"]["N"]["ICP"]["m"]["planimetric_rms"]
    assert f"{icp:.2f}" in text
    for p in report["points"][:5] + report["points"][-5:]:
        assert f"{p['h_est']:.2f}" in text
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(out), str(tmp_path / "page")], check=True)
    pages = sorted(tmp_path.glob("page*.png"))
    assert len(pages) >= 3
    assert n_images(out) == 4
    # figures given by the caller (the window's own plots) are used instead
    from PySide6.QtGui import QImage
    im = QImage(400, 300, QImage.Format.Format_RGB32)
    im.fill(0x3366AA)
    write_document(report, tmp_path / "given.pdf", figures={"vectors": im})
    assert n_images(tmp_path / "given.pdf") == 1


def n_images(pdf):
    listing = subprocess.run(["pdfimages", "-list", str(pdf)], capture_output=True, text=True,
                             check=True).stdout.splitlines()
    return sum(1 for ln in listing[2:] if " image " in ln)


def test_cli_report_pdf_and_html_from_the_dict_alone(tmp_path, capsys):
    from prismstation.cli import main
    from tests.core.synth import make_points, make_scene
    from tests.io.test_cli_pipeline import write_triplet
    sc = make_scene()
    write_triplet(tmp_path, sc, make_points(sc, n_gcp=9, n_icp=12, noise_px=0.3, seed=5))
    proj = tmp_path / "t.prismproj"
    assert main(["new", str(proj), "--scene", str(tmp_path / "scene.json"),
                 "--points", str(tmp_path / "points.csv"),
                 "--measurements", str(tmp_path / "measurements.csv")]) == 0
    assert main(["report", str(proj), "-o", str(tmp_path / "r.pdf")]) == 0
    assert main(["report", str(proj), "-o", str(tmp_path / "r.html")]) == 0
    assert main(["fit", str(proj), "--json", str(tmp_path / "r.json")]) == 0
    assert (tmp_path / "r.pdf").read_bytes()[:5] == b"%PDF-"
    rep = json.loads((tmp_path / "r.json").read_text())
    check_tables(parse((tmp_path / "r.html").read_text(encoding="utf-8")).tables, rep)


def test_single_view_and_empty_reports(tmp_path, qtbot):
    from dataclasses import replace
    from prismstation.core.scene import Scene
    from prismstation.core.solve import solve
    from tests.core.synth import make_points, make_scene
    sc = make_scene()
    single = Scene(sc.crs, sc.satellite_altitude_m, sc.track, {"N": sc.views["N"]})
    pts = [replace(p, image={"N": p.image["N"]}) for p in make_points(sc, n_gcp=6, n_icp=5)]
    rep = report_dict(solve(single, pts))
    page = parse(report_html(rep))
    assert "table2" not in page.tables and "parallax" not in page.tables
    assert len(page.tables["points"]) == 1 + 11
    empty = report_dict(solve(sc, []))
    write_document(empty, tmp_path / "e.html")
    page = parse((tmp_path / "e.html").read_text(encoding="utf-8"))
    assert page.tables["table1"][1] == ["n", "0", "0", "0", "0"] and len(page.tables["points"]) == 1
    assert "no GCP measured" in (tmp_path / "e.html").read_text(encoding="utf-8")
