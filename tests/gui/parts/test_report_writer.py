"""write_document: HTML tables hold the report dict's numbers; the PDF has them too; CLI path."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser

import pytest

from prismstation.io.report import report_dict
from prismstation.gui.report_writer import write_document
from prismstation.io.report_html import report_html


class Tables(HTMLParser):
    """``{table id: {"caption": text, "head": [...], "rows": [[cell text, ...], ...]}}`` and the
    ``src`` of every image; a heading row of one cell is the table's caption."""

    def __init__(self):
        super().__init__()
        self.tables, self.images = {}, []
        self._id = self._row = self._cell = None
        self._head = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._id = a.get("id")
            self.tables[self._id] = {"caption": "", "head": [], "rows": []}
        elif tag == "thead":
            self._head = True
        elif tag == "tr" and self._id:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []
        elif tag == "img":
            self.images.append(a.get("src", ""))

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            t = self.tables[self._id]
            if self._head and len(self._row) == 1:
                t["caption"] = self._row[0]
            elif self._head:
                t["head"] = self._row
            else:
                t["rows"].append(self._row)
            self._row = None
        elif tag == "thead":
            self._head = False
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


def by_label(table):
    return {row[0]: row[1:] for row in table["rows"]}


@pytest.fixture(scope="module")
def report(fitted):
    return report_dict(fitted[2], project_path="demo.prismproj", geoid="constant 55.0 m")


def check_tables(tables, r):
    st = r["statistics"]
    t1 = by_label(tables["table1"])
    m = st["image"]["N"]
    for j, (kind, c) in enumerate((("GCP", "x"), ("GCP", "y"), ("ICP", "x"), ("ICP", "y"))):
        assert int(t1["n"][j]) == m[kind]["m"][c]["n"]
        for label, key in (("Minimum", "min"), ("Maximum", "max"), ("RMS", "rms"), ("Mean", "mean")):
            assert num(t1[label][j]) == pytest.approx(m[kind]["m"][c][key], abs=0.0051)
    assert num(t1["Planimetric RMS"][3]) == pytest.approx(m["ICP"]["m"]["planimetric_rms"], abs=0.0051)
    t2 = by_label(tables["table2"])
    assert num(t2["Mean"][0]) == pytest.approx(st["F-N"]["mean"], abs=0.0051)
    assert num(t2["Std. dev."][1]) == pytest.approx(st["B-N"]["std"], abs=0.0051)
    t3 = by_label(tables["table3"])
    assert num(t3["RMS"][1]) == pytest.approx(st["height"]["ICP"]["rms"], abs=0.0051)
    assert num(t3["Maximum"][0]) == pytest.approx(st["height"]["GCP"]["max"], abs=0.0051)
    t4 = by_label(tables["ground"])
    assert num(t4["RMS"][2]) == pytest.approx(st["ground"]["ICP"]["x"]["rms"], abs=0.0051)
    summary = by_label(tables["summary"])
    for kind in ("GCP", "ICP"):
        g = st["ground"][kind]
        n, e, nn, plan, h, img = summary[kind]
        assert int(n) == g["x"]["n"]
        assert (num(e), num(nn), num(plan), num(h)) == pytest.approx(
            (g["x"]["rms"], g["y"]["rms"], g["planimetric_rms"], st["height"][kind]["rms"]), abs=0.0051)
        assert num(img) == pytest.approx(m[kind]["px"]["planimetric_rms"], abs=0.0051)
    par = by_label(tables["parallax"])
    assert num(par["c1 (m/px)"][0]) == pytest.approx(r["model"]["parallax"]["c1"], abs=5.1e-5)
    bias = by_label(tables["bias"])
    b5 = r["model"]["bias"]["N"]["parameters"]["B5"]
    value, std = (float(s) for s in bias["B5"][0].split("±"))
    assert value == pytest.approx(b5["value"], rel=1e-3) and std == pytest.approx(b5["std"], rel=1e-3)
    assert num(bias["σ0 (px)"][0]) == pytest.approx(r["model"]["bias"]["N"]["sigma0"], abs=5.1e-4)
    # every point with known coordinates: those beside its ground residuals
    known = [p for p in r["points"] if p.get("E_known") is not None]
    t = tables["known"]
    assert [row[0] for row in t["rows"]] == [p["id"] for p in known] != []
    for row, p in zip(t["rows"], known):
        cell = dict(zip(t["head"], row))
        assert (num(cell["E"]), num(cell["N"]), num(cell["h"])) == pytest.approx(
            (p["E_known"], p["N_known"], p["h_known"]), abs=0.00051)
        assert num(cell["dh"]) == pytest.approx(p["dh"], abs=0.0051)
        assert (cell["blunder"] == "yes") == p["blunder"]
    t = tables["residuals"]
    assert [row[0] for row in t["rows"]] == [p["id"] for p in r["points"]]
    for row, p in zip(t["rows"], r["points"]):
        cell = dict(zip(t["head"], row))
        for v, (vx, vy) in p["residual_px"].items():
            assert (num(cell[f"vx {v}"]), num(cell[f"vy {v}"])) == pytest.approx((vx, vy), abs=0.0051)
    t = tables["estimates"]
    for row, p in zip(t["rows"], r["points"]):
        cell = dict(zip(t["head"], row))
        if p.get("h_est") is not None:
            assert num(cell["h est"]) == pytest.approx(p["h_est"], abs=0.0051)
            assert num(cell["lat"]) == pytest.approx(p["lat_est"], abs=5.1e-8)
    captions = [t["caption"] for t in tables.values() if t["caption"]]
    assert [c.split(".")[0] for c in captions] == [f"Table {k}" for k in range(1, len(captions) + 1)]


def test_html_tables_match_the_report(tmp_path, report, qtbot):
    out = tmp_path / "r.html"
    write_document(report, out)
    page = parse(out.read_text(encoding="utf-8"))
    check_tables(page.tables, report)
    assert len(page.images) == 4 and all(s.startswith("data:image/png;base64,") for s in page.images)
    text = out.read_text(encoding="utf-8")
    assert "EPSG:32629" in text and "constant 55.0 m" in text and "demo.prismproj" in text
    blunder_rows = re.findall(r'<tr bgcolor="#ffd6d6"><td[^>]*>([^<]+)</td>', text)
    flagged = [p["id"] for p in report["points"] if p["blunder"]]
    assert flagged != [] and blunder_rows == flagged * 2  # known-coordinates and residual tables


def test_given_figures_are_embedded(qtbot, report):
    from PySide6.QtGui import QImage
    im = QImage(40, 30, QImage.Format.Format_RGB32)
    im.fill(0x123456)
    html = report_html(report, {"height": "fig.png"})
    assert parse(html).images == ["fig.png"]
    with pytest.raises(Exception, match="unknown document format"):
        write_document(report, "x.docx", figures={"height": im})


PRISM_IDS = {v: (f"ALPSM{v}061122750", f"O1B2R_U{v}") for v in "NFB"}
OPERATOR = "Jane Q. Operator"


@pytest.fixture(scope="module")
def prism_project(tmp_path_factory):
    """A synthetic triplet project whose scene.json carries PRISM scene and product ids,
    acquisition times and its source (as a JAXA product gives them), heights orthometric."""
    from prismstation.cli import main
    from prismstation.sim.model_triplet import make_points, make_scene
    from tests.cli.test_fit import write_triplet
    d = tmp_path_factory.mktemp("prism")
    sc = make_scene()
    write_triplet(d, sc, make_points(sc, n_gcp=9, n_icp=12, noise_px=0.3, seed=5), geoid=55.0, ortho=True)
    doc = json.loads((d / "scene.json").read_text())
    for v, (sid, pid) in PRISM_IDS.items():
        doc["views"][v].update(scene_id=sid, product_id=pid)
    doc.update(scene_id=PRISM_IDS["N"][0], times={v: f"2007-03-21T11:18:{20 + k}.5+00:00"
                                                  for k, v in enumerate("FNB")},
               product={"kind": "JAXA CEOS 1B2", "path": "/data/ALPSM061122750"})
    (d / "scene.json").write_text(json.dumps(doc))
    proj = d / "t.prismproj"
    assert main(["new", str(proj), "--scene", str(d / "scene.json"), "--points", str(d / "points.csv"),
                 "--measurements", str(d / "measurements.csv")]) == 0
    return proj


@pytest.fixture(scope="module")
def prism_report(prism_project):
    from prismstation.io.project import load_project
    from prismstation.ops.fit import fit_report
    return fit_report(load_project(prism_project), prism_project, operator=OPERATOR)[1]


def pdftext(path) -> str:
    return subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True,
                          text=True, check=True).stdout


@pytest.mark.skipif(not all(shutil.which(t) for t in ("pdftotext", "pdftoppm", "pdfimages")),
                    reason="poppler-utils not installed")
def test_pdf_a_client_can_read(tmp_path, prism_report, qtbot):
    """Page numbers, date, operator, version, scene and product ids, every point's known
    coordinates beside its residuals, the statistics; no wording about source papers."""
    from prismstation import __version__
    r = prism_report
    out = tmp_path / "r.pdf"
    write_document(r, out)
    assert out.read_bytes()[:5] == b"%PDF-"
    text = pdftext(out)
    pages = text.rstrip("\f").split("\f")
    n = len(pages)
    assert n >= 4
    for k, page in enumerate(pages, 1):
        assert f"Page {k} of {n}" in page
    created = r["header"]["created"]                      # e.g. 2026-12-01T17:49:38Z
    assert f"{created[:10]} {created[11:19]} UTC" in pages[0]
    assert OPERATOR in pages[0] and f"prismstation {__version__}" in pages[0]
    for v, (sid, pid) in PRISM_IDS.items():
        assert f"{v}: {sid} {pid}" in pages[0]
    assert "1B2R" in pages[0] and "2007-03-21 11:18:21 UTC" in pages[0] and "JAXA CEOS 1B2" in pages[0]
    assert "EPSG:32629" in text and "Table 1" in text
    known = [p for p in r["points"] if p["kind"] in ("GCP", "ICP")]
    assert len(known) == 21
    rows = {}  # id → the first line that starts with it: its row of the known-coordinates table
    for ln in text.splitlines():
        if ln.split()[:1] and ln.split()[0] in {p["id"] for p in known}:
            rows.setdefault(ln.split()[0], ln.split())
    for p in known:
        row = rows[p["id"]]
        assert row[1] == p["kind"]
        assert row[2:6] == [f"{p['E_known']:.3f}", f"{p['N_known']:.3f}", f"{p['h_known']:.3f}",
                            f"{p['H_given']:.3f}"]
        assert p["H_given"] == pytest.approx(p["h_known"] - 55.0)
        assert [float(x) for x in row[6:9]] == pytest.approx([p["dE"], p["dN"], p["dh"]], abs=0.0051)
    icp = r["statistics"]["ground"]["ICP"]["planimetric_rms"]
    assert f"{icp:.2f}" in pages[0]
    assert not re.search(r"seed|paper|eq\. ?\d|Fig\. ?\d", text, re.I)
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(out), str(tmp_path / "page")], check=True)
    assert len(list(tmp_path.glob("page*.png"))) == n
    assert n_images(out) == 4
    # figures given by the caller (the window's own plots) are used instead
    from PySide6.QtGui import QImage
    im = QImage(400, 300, QImage.Format.Format_RGB32)
    im.fill(0x3366AA)
    write_document(r, tmp_path / "given.pdf", figures={"vectors": im})
    assert n_images(tmp_path / "given.pdf") == 1


def n_images(pdf):
    listing = subprocess.run(["pdfimages", "-list", str(pdf)], capture_output=True, text=True,
                             check=True).stdout.splitlines()
    return sum(1 for ln in listing[2:] if " image " in ln)


def test_cli_report_every_format_holds_the_same_report(tmp_path, prism_project, capsys, qtbot):
    """``prismstation report`` writes the one report model as JSON, CSV, HTML and PDF; ``fit``
    prints the same header; no output speaks of source papers."""
    from prismstation.cli import main
    outs = {ext: tmp_path / f"r.{ext}" for ext in ("json", "csv", "html", "pdf")}
    for out in outs.values():
        assert main(["report", str(prism_project), "-o", str(out), "--operator", OPERATOR]) == 0
    assert main(["fit", str(prism_project)]) == 0
    printed = capsys.readouterr().out
    rep = json.loads(outs["json"].read_text())
    assert rep["header"]["operator"] == OPERATOR and rep["header"]["scene_id"] == PRISM_IDS["N"][0]
    assert rep["header"]["product_ids"] == {v: pid for v, (_, pid) in PRISM_IDS.items()}
    page = parse(outs["html"].read_text(encoding="utf-8"))
    check_tables(page.tables, rep)
    info = " ".join(" ".join(row) for row in page.tables["info"]["rows"])
    assert OPERATOR in info and "N: ALPSMN061122750 O1B2R_UN" in info
    assert f"scene {PRISM_IDS['N'][0]}" in printed and "Table 1" in printed
    texts = [outs[e].read_text(encoding="utf-8") for e in ("json", "csv", "html")] + [pdftext(outs["pdf"]), printed]
    for t in texts:
        assert not re.search(r"seed|paper|eq\. ?\d|Fig\. ?\d", t, re.I)


def test_single_view_and_empty_reports(tmp_path, qtbot):
    from dataclasses import replace
    from prismstation.core.models.solution import solve
    from prismstation.sim.model_triplet import make_points, make_scene
    sc = make_scene()
    single = replace(sc, views={"N": sc.views["N"]})
    pts = [replace(p, image={"N": p.image["N"]}) for p in make_points(sc, n_gcp=6, n_icp=5)]
    rep = report_dict(solve(single, pts))
    page = parse(report_html(rep))
    assert "table2" not in page.tables and "parallax" not in page.tables
    assert len(page.tables["residuals"]["rows"]) == len(page.tables["known"]["rows"]) == 11
    empty = report_dict(solve(sc, []))
    write_document(empty, tmp_path / "e.html")
    page = parse((tmp_path / "e.html").read_text(encoding="utf-8"))
    assert page.tables["table1"]["rows"][0] == ["n", "0", "0", "0", "0"]
    assert page.tables["residuals"]["rows"] == page.tables["known"]["rows"] == []
    assert "no GCP measured" in (tmp_path / "e.html").read_text(encoding="utf-8")


def test_accuracy_note_follows_the_orientation(report):
    assert "fit's own residuals" in report_html(report)
    dem = {**report, "header": {**report["header"], "orientation": "reference DEM"}}
    text = report_html(dem)
    assert "both independent checks" in text and "fit's own residuals" not in text
