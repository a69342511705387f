"""The project file's typed top-level records (DEM control, relocated images, product), read
back from files written before they were typed, and JSON that never holds NaN."""
import json
import math

import numpy as np
import pytest

from prismstation.errors import InputError, WriteError
from prismstation.io.jsonfile import dumps, plain, write_json
from prismstation.io.project import load_project, save_project
from prismstation.io.recovery import Journal, recover
from prismstation.model.points import GroundPoint, Measurement
from prismstation.model.project import Project
from prismstation.sim.model_triplet import make_scene
from tests.cli.test_fit import write_triplet

RECORD = {"reference": "srtm.tif", "mean_height": 312.5, "offsets_px": {"F": [0.5, -1.0]},
          "patches": [{"window": [0, 0, 10, 10], "x": 5.0, "y": 5.0, "dE": None, "dN": None, "dh": 1.5,
                       "sigma_E": None, "sigma_N": None, "sigma_h": 0.5, "used": False}]}


@pytest.fixture
def scene_path(tmp_path):
    write_triplet(tmp_path, make_scene(size=2000), [])
    return tmp_path / "scene.json"


def test_a_file_written_with_the_old_top_level_keys_loads_into_the_typed_fields(tmp_path, scene_path):
    old = {"format": "prismstation-project/1", "scene": "scene.json", "settings": {},
           "geoid": {"kind": "constant", "value": 50.0},
           "points": [{"id": "A", "kind": "GCP", "E": 540100.0, "N": 4560100.0, "H": 300.0}],
           "measurements": [{"id": "A", "view": "N", "x": 10.0, "y": 20.0}],
           "dem_control": RECORD, "relocated_images": {"N": "/moved/N.tif"},
           "product": "/data/ALPSMN", "note": "from a newer program", "recovery": {"revision": 3}}
    (tmp_path / "old.prismproj").write_text(json.dumps(old))
    p = load_project(tmp_path / "old.prismproj")
    assert p.revision == 0 and p.dem_control == RECORD
    assert p.relocations == {"N": "/moved/N.tif"} and p.product == "/data/ALPSMN"
    assert p.other == {"note": "from a newer program"}             # kept, written back
    save_project(p, tmp_path / "new.prismproj")
    again = json.loads((tmp_path / "new.prismproj").read_text())
    for k in ("dem_control", "relocated_images", "product", "note"):
        assert again[k] == old[k]
    assert "recovery" not in again


def test_a_malformed_record_is_an_input_error_with_its_line(tmp_path, scene_path):
    doc = {"format": "prismstation-project/1", "scene": "scene.json",
           "relocated_images": {"N": 5}}
    (tmp_path / "bad.prismproj").write_text(json.dumps(doc, indent=1))
    with pytest.raises(InputError, match="relocated_images") as e:
        load_project(tmp_path / "bad.prismproj")
    assert e.value.line == 4


def test_the_project_file_holds_null_where_numbers_are_nan(tmp_path, scene_path):
    from prismstation.io.scene import read_scene
    p = Project(read_scene(scene_path), str(scene_path),
                dem_control={"patches": [{**dict.fromkeys(("x", "y", "dN", "dh", "sigma_E", "sigma_N", "sigma_h"), 1.0),
                                          "dE": float("nan"), "sigma": np.float32(np.inf)}]})
    p.add_tie("T1")
    p.set_measurement(Measurement("T1", "N", 1.0, 2.0))
    save_project(p, tmp_path / "p.prismproj")
    text = (tmp_path / "p.prismproj").read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text)
    patch = doc["dem_control"]["patches"][0]
    assert doc["points"][0]["E"] is None and patch["dE"] is None and patch["sigma"] is None
    assert math.isnan(load_project(tmp_path / "p.prismproj").points["T1"].E)


def test_plain_and_dumps_never_write_nan(tmp_path):
    v = {"a": np.array([1.0, np.nan]), "b": (np.float64(-np.inf), np.int64(3), np.bool_(True)), 4: "é"}
    assert plain(v) == {"a": [1.0, None], "b": [None, 3, True], "4": "é"}
    assert json.loads(dumps(v)) == plain(v) and "é" in dumps(v)
    write_json(tmp_path / "x.json", {"v": float("nan")})
    assert json.loads((tmp_path / "x.json").read_text()) == {"v": None}
    with pytest.raises(WriteError, match="cannot write"):
        write_json(tmp_path / "x.json" / "under_a_file.json", {})


def test_the_journal_records_every_change_and_recovery_counts_as_modified(tmp_path, scene_path):
    from prismstation.io.scene import read_scene
    p = Project(read_scene(scene_path), str(scene_path))
    path = tmp_path / "j.prismproj"
    j = Journal(p, path)
    with p.batch():
        p.add_point(GroundPoint("A", 540100.0, 4560100.0, 300.0))
        p.set_dem_control(RECORD)
    j.close()
    r = recover(path)
    assert r.revision == 1 and r.dem_control == RECORD and list(r.points) == ["A"]
    assert "recovery" not in r.other


def test_version_2_files_open_and_the_orientation_keys_are_checked(tmp_path, scene_path):
    """A version-2 file (no stored orientation, none of the settings of a bias per view) opens
    with their defaults and is saved as version 3 without them; the new keys are checked with
    their line (a PRISM triplet has one bias model for every view and is fitted to its GCPs)."""
    doc = {"format": "prismstation-project/2", "scene": "scene.json", "settings": {"bias_model": "shift"},
           "points": [], "measurements": []}
    (tmp_path / "v2.prismproj").write_text(json.dumps(doc, indent=1))
    p = load_project(tmp_path / "v2.prismproj")
    assert p.orientation is None and p.settings.view_bias == () and p.settings.use_gcps
    assert p.settings.reference_sigma_m is None
    save_project(p, tmp_path / "v3.prismproj")
    again = json.loads((tmp_path / "v3.prismproj").read_text())
    assert again["format"] == "prismstation-project/3" and "orientation" not in again
    assert not {"view_bias", "reference_sigma_m", "use_gcps"} & set(again["settings"])
    for settings, key in (({"view_bias": {"F": "shift"}}, "view_bias"), ({"use_gcps": False}, "use_gcps"),
                          ({"reference_sigma_m": -1}, "reference_sigma_m"), ({"view_bias": ["F"]}, "view_bias")):
        (tmp_path / "bad.prismproj").write_text(json.dumps({**doc, "format": "prismstation-project/3",
                                                            "settings": settings}, indent=1))
        with pytest.raises(InputError, match=key) as e:
            load_project(tmp_path / "bad.prismproj")
        assert e.value.line is not None
    (tmp_path / "bad.prismproj").write_text(json.dumps({**doc, "format": "prismstation-project/3",
                                                        "orientation": [1]}, indent=1))
    with pytest.raises(InputError, match="orientation"):
        load_project(tmp_path / "bad.prismproj")
    # a version-2 file's "orientation" is not read as a stored orientation
    (tmp_path / "old.prismproj").write_text(json.dumps({**doc, "orientation": {"views": {}}}))
    assert load_project(tmp_path / "old.prismproj").orientation is None
