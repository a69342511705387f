"""The command line on fuzzed files: exit 0, or exit 2 with exactly one line on stderr that
names the bad file — never a traceback. In-process through ``prismstation.cli.main`` (fast),
and a handful through a real process."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from prismstation.cli import main
from prismstation.ops.project import create
from prismstation.errors import PrismError
from prismstation.io.project import load_project, project_to_dict
from tests.robustness import fuzzlib as fz


@pytest.fixture(scope="module")
def work():
    d = Path(tempfile.mkdtemp(prefix="prism_cli_fuzz_"))
    (d / "scene.json").write_text(json.dumps(fz.scene_doc(), indent=1))
    (d / "points.csv").write_text(fz.points_csv_text())
    (d / "measurements.csv").write_text(fz.measurements_csv_text())
    yield d
    shutil.rmtree(d, ignore_errors=True)


def run_cli(capsys, argv, bad: Path | None):
    """Run ``main(argv)`` and check the command-line contract; returns the exit status."""
    capsys.readouterr()
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse only; the arguments here are always well-formed
        raise AssertionError(f"SystemExit({exc.code}) from {argv}") from None
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    if rc == 0:
        assert out.strip(), "success without output"
    else:
        lines = err.strip().split("\n")
        assert rc == 2 and len(lines) == 1 and lines[0].strip(), (rc, err)
        assert lines[0].startswith(f"prismstation {argv[0]}: ")
        assert bad is None or bad.name in lines[0], f"the message does not name {bad.name}: {lines[0]}"
    return rc


@fz.fuzz_settings(150)
@given(which=st.sampled_from(["points", "measurements"]), data=st.data())
def test_fuzz_new(work, capsys, which, data):
    base = fz.points_csv_text() if which == "points" else fz.measurements_csv_text()
    bad = work / f"fuzz_{which}.csv"
    bad.write_bytes(data.draw(fz.any_input(base)))
    files = {"points": work / "points.csv", "measurements": work / "measurements.csv", which: bad}
    run_cli(capsys, ["new", work / "out.prismproj", "--force", "--scene", work / "scene.json",
                     "--points", files["points"], "--measurements", files["measurements"]], bad)


@fz.fuzz_settings(100)
@given(data=fz.any_input(json.dumps(fz.scene_doc(), indent=1), fz.scene_doc()))
def test_fuzz_new_scene(work, capsys, data):
    bad = work / "fuzz_scene.json"
    bad.write_bytes(data)
    run_cli(capsys, ["new", work / "out2.prismproj", "--force", "--scene", bad,
                     "--points", work / "points.csv", "--measurements", work / "measurements.csv"], bad)


@pytest.mark.parametrize("fmt,ext,out_ext", [("qgis", ".points", ".csv"), ("odm", ".txt", ".gcp"),
                                             ("asp", ".gcp", ".txt"), ("csv", ".csv", ".points")])
def test_fuzz_points_command(work, capsys, fmt, ext, out_ext):
    base = fz.point_file_text(fmt)

    @fz.fuzz_settings(80)
    @given(data=fz.any_input(base), to_crs=st.sampled_from([None, "EPSG:32630", "EPSG:4326"]))
    def run(data, to_crs):
        bad = work / f"fuzz_in{ext}"
        bad.write_bytes(data)
        argv = ["points", bad, "-o", work / f"fuzz_out{out_ext}", "--measurements", work / "fm.csv"]
        if to_crs:
            argv += ["--to-crs", to_crs]
        if fmt == "csv":
            argv += ["--crs", "EPSG:32629"]
        if out_ext == ".points":
            argv += ["--view", "N"]
        run_cli(capsys, argv, bad)

    run()


@pytest.mark.parametrize("fmt,ext,spoil,extra", [
    # found by fuzzing: an ellipsoid pyproj puts on another celestial body (ProjError)
    ("qgis", ".points", lambda t: t.replace("6378137", "1e300", 1), ["--to-crs", "EPSG:32630"]),
    # found by fuzzing: a longitude of 1000 passed the ASP reader, then failed in the conversion
    ("asp", ".gcp", lambda t: t.replace("-8.", "1_000.", 1), ["--to-crs", "EPSG:32630"]),
])
def test_found_point_file_cases(work, capsys, fmt, ext, spoil, extra):
    bad = work / f"found{ext}"
    bad.write_text(spoil(fz.point_file_text(fmt)))
    assert run_cli(capsys, ["points", bad, "-o", work / "found_out.csv"] + extra, bad) == 2


def test_fuzz_fit_project(work, capsys):
    """A project file that reads may still carry wrong types: fitting it must not crash."""
    pdir = work / "proj"
    pdir.mkdir(exist_ok=True)
    shutil.copy(work / "scene.json", pdir / "scene.json")
    proj = create(pdir / "valid.prismproj", pdir / "scene.json", work / "points.csv",
                  work / "measurements.csv", geoid="55.2", force=True)
    doc = project_to_dict(proj, pdir / "valid.prismproj")
    assert run_cli(capsys, ["fit", pdir / "valid.prismproj"], pdir / "valid.prismproj") == 0
    # found by fuzzing: wrong types in settings / geoid crashed the fit (KeyError, AttributeError)
    for key, value in (("settings", dict(doc["settings"], bias_model=None)),
                       ("settings", dict(doc["settings"], sigma_px="1")), ("geoid", [None])):
        bad = pdir / "found.prismproj"
        bad.write_text(json.dumps(dict(doc, **{key: value})))
        assert run_cli(capsys, ["fit", bad], bad) == 2

    @fz.fuzz_settings(120)
    @given(data=fz.mutated_json(doc))
    def run(data):
        bad = pdir / "fuzz.prismproj"
        bad.write_bytes(data)
        try:
            load_project(bad)
        except PrismError:
            run_cli(capsys, ["fit", bad], bad)  # the file is bad: it must be named
        else:  # the file reads; the model may still not fit (too few GCPs left): one line
            run_cli(capsys, ["fit", bad], None)

    run()


# ----------------------------------------------------------------------- a real process
def _prismstation() -> list[str]:
    exe = Path(sys.executable).parent / "prismstation"
    if exe.exists():
        return [str(exe)]
    return [sys.executable, "-c", "import sys; from prismstation.cli import main; sys.exit(main())"]


SUBPROCESS_CASES = [
    ("new", "measurements.csv", lambda t: t + "P99,N,12.5,notanumber\n"),
    ("new", "points.csv", lambda t: "\x00\xff binary \x89PNG\r\n"),
    ("new", "scene.json", lambda t: t[: len(t) // 2]),
    ("points", "gcp_list.txt", lambda t: t.replace("\n", "\n1 2\n", 1)),
    ("points", "in.points", lambda t: t.replace("mapX", "mapZ")),
]


@pytest.mark.parametrize("cmd,name,spoil", SUBPROCESS_CASES)
def test_bad_file_in_a_real_process(work, cmd, name, spoil):
    d = work / f"sub_{cmd}_{name}"
    d.mkdir()
    for f in ("scene.json", "points.csv", "measurements.csv"):
        shutil.copy(work / f, d / f)
    if cmd == "points":
        base = fz.point_file_text("odm" if name.endswith(".txt") else "qgis")
    else:
        base = (d / name).read_text(encoding="utf-8")
    (d / name).write_text(spoil(base), encoding="utf-8", errors="surrogateescape")
    argv = (["new", d / "x.prismproj", "--scene", d / "scene.json", "--points", d / "points.csv",
             "--measurements", d / "measurements.csv"] if cmd == "new"
            else ["points", d / name, "-o", d / "out.csv"])
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    r = subprocess.run(_prismstation() + [str(a) for a in argv], capture_output=True, text=True,
                       timeout=120, env=env)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().split("\n")
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert name in lines[0] and lines[0].startswith(f"prismstation {cmd}: ")
    assert not (d / "x.prismproj").exists()
