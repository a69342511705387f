"""Property-based fuzzing of every reader: random bytes, and valid documents mutated line by
line, field by field, number by number, re-encoded and re-typed (JSON). Each read either
succeeds or raises a PrismError naming the file (and the line, where there is one) — never
another exception. Valid documents read back to what was written.
"""
from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from prismstation.ops.project import create
from prismstation.errors import InputError
from prismstation.io import pointfiles as pfm
from prismstation.io.points import read_ground_points, read_measurements
from prismstation.io.project import load_project, project_to_dict
from prismstation.io.scene import read_scene
from tests.robustness import fuzzlib as fz


@pytest.fixture(scope="module")
def work():
    d = Path(tempfile.mkdtemp(prefix="prism_fuzz_"))
    yield d
    shutil.rmtree(d, ignore_errors=True)


# --------------------------------------------------------------------------- valid inputs read
def test_valid_documents_read(work):
    (work / "scene.json").write_text(json.dumps(fz.scene_doc()))
    sc = read_scene(work / "scene.json")
    assert set(sc.views) == {"N", "F", "B"} and sc.geoid_undulation_m == 55.2
    points, meas = fz.synth_points()
    (work / "p.csv").write_text(fz.points_csv_text())
    got = read_ground_points(work / "p.csv")
    assert [(p.id, p.E, p.N, p.H, p.kind, p.height_kind, p.sigma_xy_m) for p in got] == \
        [(p.id, p.E, p.N, p.H, p.kind, p.height_kind, p.sigma_xy_m) for p in points]
    (work / "m.csv").write_text(fz.measurements_csv_text())
    got = read_measurements(work / "m.csv", views=["N", "F", "B"])
    assert [(m.id, m.view, m.x, m.y, m.sigma_px) for m in got] == \
        [(m.id, m.view, m.x, m.y, m.sigma_px) for m in meas]
    for fmt, ext in (("qgis", ".points"), ("odm", ".txt"), ("asp", ".gcp"), ("csv", ".csv")):
        f = work / f"valid{ext}"
        f.write_text(fz.point_file_text(fmt))
        pf = pfm.read_point_file(f)
        want = fz.point_file(fmt)
        assert pf.format == fmt and [p.id for p in pf.points] == [p.id for p in want.points]
        ids = {p.id for p in want.points}  # writers leave out measurements of tie points
        assert len(pf.measurements) == len([m for m in want.measurements if m.id in ids])


# --------------------------------------------------------------------------- scene.json
SCENE_DOC = fz.scene_doc()


@fz.fuzz_settings(400)
@given(data=fz.any_input(json.dumps(SCENE_DOC, indent=1), SCENE_DOC))
def test_fuzz_scene(work, data):
    path = work / "fuzz_scene.json"
    out = fz.check_reader(read_scene, path, data, lined=False)
    if isinstance(out, InputError):
        fz.json_error_has_line(out, data)
    elif not isinstance(out, Exception):
        assert out.satellite_altitude_m > 0 and out.views
        for v in out.views.values():
            assert fz.finite(v.map_to_image.matrix) and v.pixel_size_m > 0


def test_scene_with_garbage_image(work):
    """An existing image path that is not a raster: the view's image is named, no rasterio traceback."""
    doc = fz.scene_doc()
    doc["views"]["N"].pop("map_to_image")
    (work / "N.tif").write_bytes(b"II*\x00garbage" * 10)
    (work / "sc.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"sc\.json.*N\.tif"):
        read_scene(work / "sc.json")


# --------------------------------------------------------------------------- ground points / measurements
@pytest.mark.slow  # 11–14 s (measured, -n 0)
@fz.fuzz_settings(500)
@given(data=fz.any_input(fz.points_csv_text()), convert=st.booleans())
@example(data=b'"\x00\xc2\x85\x00', convert=False)  # found: a newline inside the one-line message
def test_fuzz_ground_points(work, data, convert):
    path = work / "fuzz_points.csv"
    kw = {"crs": "EPSG:32629", "to_crs": "EPSG:32630"} if convert else {}
    out = fz.check_reader(lambda p: read_ground_points(p, **kw), path, data, lined=True)
    if isinstance(out, list):
        ids = [p.id for p in out]
        assert len(ids) == len(set(ids)) and all(ids)
        assert all(fz.finite(p.E, p.N, p.H) for p in out)


@fz.fuzz_settings(500)
@given(data=fz.any_input(fz.measurements_csv_text()), restrict=st.booleans())
def test_fuzz_measurements(work, data, restrict):
    path = work / "fuzz_meas.csv"
    views = ["N", "F", "B"] if restrict else None
    out = fz.check_reader(lambda p: read_measurements(p, views=views), path, data, lined=True)
    if isinstance(out, list):
        assert all(fz.finite(m.x, m.y) for m in out)
        assert all(m.sigma_px is None or m.sigma_px > 0 for m in out)


# --------------------------------------------------------------------------- projects
@pytest.fixture(scope="module")
def project_doc(work):
    pdir = work / "proj"
    pdir.mkdir()
    (pdir / "scene.json").write_text(json.dumps(fz.scene_doc()))
    (pdir / "p.csv").write_text(fz.points_csv_text())
    (pdir / "m.csv").write_text(fz.measurements_csv_text())
    proj = create(pdir / "valid.prismproj", pdir / "scene.json", pdir / "p.csv", pdir / "m.csv",
                  geoid="55.2")
    loaded = load_project(pdir / "valid.prismproj")
    assert set(loaded.points) == set(proj.points) and set(loaded.measurements) == set(proj.measurements)
    return pdir, project_to_dict(proj, pdir / "valid.prismproj")


def test_fuzz_project(project_doc):
    pdir, doc = project_doc

    @fz.fuzz_settings(400)
    @given(data=fz.any_input(json.dumps(doc, indent=1), doc))
    def run(data):
        out = fz.check_reader(load_project, pdir / "fuzz.prismproj", data, lined=False)
        if isinstance(out, InputError):
            fz.json_error_has_line(out, data)
        elif not isinstance(out, Exception):
            for m in out.measurements.values():
                assert m.view in out.scene.views and fz.finite(m.x, m.y)

    run()


def test_newer_project_refused_untouched(project_doc):
    pdir, doc = project_doc
    newer = dict(doc, format="prismstation-project/99")
    f = pdir / "newer.prismproj"
    f.write_text(json.dumps(newer))
    before = f.read_bytes()
    with pytest.raises(InputError, match="newer"):
        load_project(f)
    assert f.read_bytes() == before


# --------------------------------------------------------------------------- other tools' point files
FORMATS = [("qgis", ".points"), ("odm", ".txt"), ("asp", ".gcp"), ("csv", ".csv")]


@pytest.mark.parametrize("fmt,ext", FORMATS)
def test_fuzz_point_files(work, fmt, ext):
    base = fz.point_file_text(fmt)

    # ODM: a spoiled CRS line (often a data row moved up) costs pyproj ~0.3 s to refuse
    @fz.fuzz_settings(100 if fmt == "odm" else 300)
    @given(data=fz.any_input(base), detect=st.booleans())
    def run(data, detect):
        path = work / f"fuzz_{fmt}{ext if detect else '.dat'}"
        out = fz.check_reader(lambda p: pfm.read_point_file(p, None if detect else fmt), path, data,
                              lined=True)
        if isinstance(out, pfm.PointFile):
            assert all(fz.finite(p.E, p.N, p.H) for p in out.points)
            assert all(fz.finite(m.x, m.y) for m in out.measurements)

    run()


@fz.fuzz_settings(300)
@given(data=st.one_of([fz.mutated_text(fz.point_file_text(f)) for f, _ in FORMATS] + [st.binary(max_size=400)]))
def test_fuzz_point_file_detection(work, data):
    """Content-based detection (no telling extension) on any format's mutations."""
    fz.check_reader(pfm.read_point_file, work / "fuzz_detect.txt", data, lined=True)


@fz.fuzz_settings(30)  # pyproj looks unknown names up in its database: ~0.3 s each
@given(text=st.one_of(st.sampled_from(fz.NASTY), st.text(max_size=12)))
def test_fuzz_parse_crs(text):
    try:
        crs = pfm.parse_crs(text, "crs.txt", 3)
    except InputError as exc:
        assert "crs.txt, line 3" in str(exc)
    else:
        assert pfm.metres_per_unit(text) > 0 if crs.is_projected or crs.is_geographic else True


def test_missing_files_are_named(work):
    gone = work / "does_not_exist.csv"
    for read in (read_scene, read_ground_points, read_measurements, load_project,
                 pfm.read_point_file, pfm.read_qgis_points, pfm.read_odm_gcp, pfm.read_asp_gcp):
        with pytest.raises(InputError, match="does_not_exist"):
            read(gone)
    with pytest.raises(InputError, match="prism_fuzz_"):
        read_ground_points(work)  # a folder, not a file


@pytest.mark.parametrize("bad_path", ["\x00", "a\x00b.tif", "x" * 300, "/", ""])
def test_unusable_paths_in_documents(project_doc, bad_path):
    """Found by fuzzing: pathlib's ValueError / OSError escaped from image and scene paths."""
    pdir, doc = project_doc
    scene = fz.scene_doc()
    scene["views"]["F"]["image"] = bad_path
    scene["views"]["F"].pop("map_to_image")
    f = pdir / "bad_scene.json"
    f.write_text(json.dumps(scene))
    with pytest.raises(InputError, match=r"bad_scene\.json"):
        read_scene(f)
    p = pdir / "bad_path.prismproj"
    p.write_text(json.dumps(dict(doc, scene=bad_path)))
    with pytest.raises(InputError, match=r"bad_path\.prismproj"):
        load_project(p)


def test_integers_beyond_float_range(project_doc):
    """Found by fuzzing: a JSON integer of 400 digits raised OverflowError."""
    pdir, doc = project_doc
    big = 10 ** 400
    for change in (lambda d: d.update(satellite_altitude_m=big),
                   lambda d: d["ground_track"][0].__setitem__(0, big),
                   lambda d: d["views"]["N"].update(pixel_size_m=big)):
        scene = fz.scene_doc()
        change(scene)
        f = pdir / "big_scene.json"
        f.write_text(json.dumps(scene))
        with pytest.raises(InputError, match=r"big_scene\.json, line \d+"):
            read_scene(f)
    for change in ({"settings": dict(doc["settings"], sigma_px=big)},
                   {"points": [dict(doc["points"][0], E=big)]},
                   {"measurements": [dict(doc["measurements"][0], x=big)]}):
        p = pdir / "big.prismproj"
        p.write_text(json.dumps(dict(doc, **change)))
        with pytest.raises(InputError, match=r"big\.prismproj"):
            load_project(p)
