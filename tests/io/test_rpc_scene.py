"""The RPC view of a scene file (``prismstation-scene/2``): written by ``new --images``, read back
to the same model, bad files named with their line."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.core.models.rpc_model import RpcModel
from prismstation.errors import InputError
from prismstation.io.project import load_project
from prismstation.io.rpc import read_rpc
from prismstation.io.rpc_scene import write_scene_for_images
from prismstation.io.scene import read_scene

PAIR = ["pleiades_pair_reunion/img_01.tif", "pleiades_pair_reunion/img_02.tif"]


@pytest.fixture
def scene_file(shared_data, tmp_path):
    return write_scene_for_images([shared_data / f for f in PAIR], tmp_path / "s.scene.json")


def test_the_scene_file_keeps_the_rpc_to_the_last_digit(shared_data, scene_file):
    scene = read_scene(scene_file)
    assert scene.sensor is RpcModel and list(scene.views) == ["img_01", "img_02"]
    assert scene.crs.startswith("EPSG:327")              # La Réunion: UTM south
    rng = np.random.default_rng(0)
    for f, (name, view) in zip(PAIR, scene.views.items()):
        rpc = read_rpc(shared_data / f)
        assert view.shape is not None and view.pixel_size_m > 0
        lon = rpc.lon_off + rng.uniform(-0.5, 0.5, 50) * rpc.lon_scale
        lat = rpc.lat_off + rng.uniform(-0.5, 0.5, 50) * rpc.lat_scale
        h = rpc.h_off + rng.uniform(-0.5, 0.5, 50) * rpc.h_scale
        np.testing.assert_array_equal(np.column_stack(view.rpc.project(lon, lat, h)),
                                      np.column_stack(rpc.project(lon, lat, h)))


def _broken(scene_file, edit):
    data = json.loads(scene_file.read_text())
    edit(data)
    scene_file.write_text(json.dumps(data, indent=1))
    with pytest.raises(InputError) as exc:
        read_scene(scene_file)
    return str(exc.value)


def test_bad_rpc_scenes_are_named(scene_file):
    text = scene_file.read_text()
    msg = _broken(scene_file, lambda d: d.update(format="prismstation-scene/1"))
    assert 'needs "format": "prismstation-scene/2"' in msg
    scene_file.write_text(text)
    msg = _broken(scene_file, lambda d: d["views"]["img_02"].pop("model"))
    assert "one sensor model" in msg
    scene_file.write_text(text)
    msg = _broken(scene_file, lambda d: d["views"]["img_01"].update(model="rational"))
    assert "'rational' is not a sensor model" in msg
    scene_file.write_text(text)
    msg = _broken(scene_file, lambda d: d["views"]["img_02"]["rpc"].pop("samp_den"))
    assert "missing samp_den" in msg and "line" in msg
    scene_file.write_text(text)
    msg = _broken(scene_file, lambda d: d["views"]["img_02"]["rpc"].update(line_num=[1.0] * 19))
    assert "views.img_02" in msg


def test_new_images_names_views_by_stem_and_refuses_twins(shared_data, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    for d in (a, b):
        shutil.copy(shared_data / PAIR[0], d / "img.tif")
    assert main(["new", str(tmp_path / "p.prismproj"), "--images", str(a / "img.tif"), str(b / "img.tif")]) == 2
    assert main(["new", str(tmp_path / "p.prismproj"), "--images", *(str(shared_data / f) for f in PAIR), "--no-ties"]) == 0
    project = load_project(tmp_path / "p.prismproj")
    assert project.scene.sensor is RpcModel and project.settings.bias_model == "shift"
    assert main(["new", str(tmp_path / "p.prismproj"), "--images", *(str(shared_data / f) for f in PAIR), "--no-ties"]) == 2
    assert main(["new", str(tmp_path / "q.prismproj"), "--images", str(tmp_path / "none.tif"),
                 str(shared_data / PAIR[0])]) == 2


def test_project_settings_are_checked_against_the_sensor_model(shared_data, tmp_path):
    assert main(["new", str(tmp_path / "p.prismproj"), "--images", *(str(shared_data / f) for f in PAIR), "--no-ties"]) == 0
    path = tmp_path / "p.prismproj"
    data = json.loads(path.read_text())
    data["settings"]["bias_model"] = "similarity"
    path.write_text(json.dumps(data, indent=1))
    with pytest.raises(InputError, match="settings.bias_model"):
        load_project(path)
    data["settings"].update(bias_model="shift_drift", fixed_view="img_09")
    path.write_text(json.dumps(data, indent=1))
    with pytest.raises(InputError, match="settings.fixed_view"):
        load_project(path)
    data["settings"]["fixed_view"] = "img_02"
    path.write_text(json.dumps(data, indent=1))
    assert load_project(path).settings.fixed_view == "img_02"


def test_a_command_the_model_does_not_list_is_refused_in_one_line(shared_data, tmp_path, capsys, monkeypatch):
    """``ops.project.require_workflow``: a sensor model whose ``workflows`` do not list a
    command (here the RPC model with ``orient-dem`` and ``dsm`` taken out) refuses it."""
    from prismstation.core.models.rpc_model import RpcModel
    monkeypatch.setattr(RpcModel, "workflows", frozenset({"fit", "report"}))
    proj = tmp_path / "p.prismproj"
    assert main(["new", str(proj), "--images", *(str(shared_data / f) for f in PAIR), "--no-ties"]) == 0
    capsys.readouterr()
    assert main(["orient-dem", str(proj), str(shared_data / PAIR[0])]) == 2
    assert main(["dsm", str(proj), "-o", str(tmp_path / "dsm.tif")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"prismstation orient-dem: {proj}: orient-dem is not available yet for images with RPCs "
                   "(on this project: fit, report)",
                   f"prismstation dsm: {proj}: dsm is not available yet for images with RPCs "
                   "(on this project: fit, report)"]
    assert not (tmp_path / "dsm.tif").exists()


# ----------------------------------------------------------------- the map zone, overlap
def _tagged(path, rpc, size=64):
    from tests.cli.test_rpc_workflows import write_tagged
    write_tagged(path, np.zeros((size, size), np.float32), rpc)
    return path


def _wide_rpc(lon0, lat0, half_deg, seed=0):
    """The RPC of a 64 px image ``2 × half_deg`` degrees of longitude wide, centred on
    ``(lon0, lat0)``."""
    from tests.ops.rpc_synth import make_rpc
    from prismstation.core.models.rpc_bias import metres_per_degree
    ke, _ = metres_per_degree(lat0)
    return make_rpc(lon0, lat0, gsd=half_deg * ke / 32, size=64, tan_along=0.0, seed=seed)


def test_the_zone_is_the_common_footprints_not_the_mean_offsets(tmp_path):
    """Offsets at 5.5° and 6.7° E (their mean in UTM 32), footprints meeting only between
    5.9° and 5.95° E: UTM 31."""
    a = _tagged(tmp_path / "a.tif", _wide_rpc(5.5, 44.0, 0.45))
    b = _tagged(tmp_path / "b.tif", _wide_rpc(6.7, 44.0, 0.8, seed=1))
    scene = read_scene(write_scene_for_images([a, b], tmp_path / "s.scene.json"))
    assert scene.crs == "EPSG:32631"


def test_images_across_the_antimeridian(tmp_path):
    """Two images over Fiji's 180th meridian, 179.8°–180° and 179.95°–180.15° E: their
    offsets' mean would be −0.025° (UTM 30); the common footprint lies just west of 180° (UTM
    60 south), and the scene's model works there."""
    a = _tagged(tmp_path / "a.tif", _wide_rpc(179.9, -16.5, 0.1))
    b = _tagged(tmp_path / "b.tif", _wide_rpc(-179.95, -16.5, 0.1, seed=1))
    scene = read_scene(write_scene_for_images([a, b], tmp_path / "s.scene.json"))
    assert scene.crs == "EPSG:32760"
    from prismstation.core.models.rpc_bias import metres_per_degree
    gsd = 0.1 * metres_per_degree(-16.5)[0] / 32          # the RPCs' own, about 334 m
    for name, view in scene.views.items():
        assert abs(view.pixel_size_m / gsd - 1) < 0.02, (name, view.pixel_size_m, gsd)
    ground = scene.views["a"].footprint()
    assert np.isfinite(ground).all()
    assert np.all(np.abs(ground[:, 0] - ground[0, 0]) < 30e3)   # one zone: no jump of a turn


def test_images_that_do_not_overlap_are_refused_in_one_line(shared_data, tmp_path, capsys):
    """Buenos Aires (the WorldView-3 NITF) and Nice (the Pléiades DIMAP crop)."""
    fmt = shared_data / "rpc_formats"
    images = [fmt / "wv3_20.NTF", fmt / "PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"]
    assert main(["new", str(tmp_path / "p.prismproj"), "--images", *map(str, images)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"prismstation new: the images do not overlap: {images[0].name} and {images[1].name} "
                   "see no common ground (footprints at their RPCs' height offsets): a project needs "
                   "images of one place"]
    assert not (tmp_path / "p.prismproj").exists() and not (tmp_path / "p.scene.json").exists()
