"""``prismstation ortho`` and ``validate-ortho`` through the command line: files, output, JSON
without NaN, an SVG that parses, and bad input as one line with exit status 2."""
import json
import xml.etree.ElementTree as ET

import pytest

from prismstation.cli import main
from prismstation.io.ortho import read_ortho_info
from prismstation.sim import simulate


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    d = tmp_path_factory.mktemp("ortho_cli")
    simulate(d, size=400, seed=3)
    assert main(["new", str(d / "p.prismproj"), "--scene", str(d / "scene.json"), "--points",
                 str(d / "points.csv"), "--measurements", str(d / "measurements.csv")]) == 0
    return d


def test_ortho_and_its_validation(sim, capsys):
    capsys.readouterr()
    assert main(["ortho", str(sim / "p.prismproj"), "-o", str(sim / "o.tif"), "--view", "all", "--dem",
                 str(sim / "truth_dem.tif"), "--dem-heights", "ellipsoidal", "--json", str(sim / "o.json")]) == 0
    out = capsys.readouterr().out
    assert out.count("wrote ") == 3 and "expected planimetric accuracy" in out and "check points" in out
    record = json.loads((sim / "o.json").read_text())
    assert [o["view"] for o in record["orthos"]] == ["N", "F", "B"] and "NaN" not in (sim / "o.json").read_text()
    assert read_ortho_info(sim / "o_F.tif")["tags"]["ORTHO_VIEW"] == "F"
    assert main(["validate-ortho", str(sim / "p.prismproj"), str(sim / "o_F.tif"), "--json", str(sim / "v.json"),
                 "--plot", str(sim / "v.svg")]) == 0
    out = capsys.readouterr().out
    assert "ICP:" in out and "GCP:" in out and "expected accuracy" in out
    v = json.loads((sim / "v.json").read_text())
    assert v["view"] == "F" and v["stats"]["ICP"]["n"] >= 35
    # the ICPs' scatter against the ortho's stated accuracy: the points carry their 0.3 px
    # measurement noise (0.75 m per axis) beside it
    assert v["stats"]["ICP"]["rmse_m"] < 3 * max(v["expected_sigma_m"], 0.75 * 2 ** 0.5)
    svg = ET.parse(sim / "v.svg").getroot()
    assert svg.tag.endswith("svg") and len(svg.findall(".//{http://www.w3.org/2000/svg}line")) >= 35


def test_a_constant_height_warns_on_stderr(sim, capsys):
    capsys.readouterr()
    assert main(["ortho", str(sim / "p.prismproj"), "-o", str(sim / "c.tif"), "--height", "150",
                 "--posting", "5", "--resampling", "cubic"]) == 0
    cap = capsys.readouterr()
    assert "warning: no DEM" in cap.err and "at 5 m" in cap.out


@pytest.mark.parametrize("args, words", [
    (["--dem", "missing.tif"], "DEM not found"),
    (["--view", "X"], "not a view of the project"),
    (["--window", "5000", "0", "10", "10"], "outside"),
    (["--posting", "-1"], "positive"),
])
def test_bad_input_is_one_line_and_status_2(sim, capsys, args, words):
    capsys.readouterr()
    assert main(["ortho", str(sim / "p.prismproj"), "-o", str(sim / "bad.tif"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prismstation ortho:") and words in err[0]
    assert not (sim / "bad.tif").exists()


def test_validating_a_file_that_is_no_ortho(sim, capsys):
    capsys.readouterr()
    assert main(["validate-ortho", str(sim / "p.prismproj"), str(sim / "truth_dem.tif")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not an orthoimage" in err[0] and "truth_dem.tif" in err[0]
