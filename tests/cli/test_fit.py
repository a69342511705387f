"""A triplet written outside the project, in docs/formats.md's formats, through new → fit --json."""
import csv
import json
import math

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.sim.model_triplet import make_points, make_scene


def write_triplet(tmp_path, scene, pts, geoid=None, ortho=False):
    views = {}
    for name, v in scene.views.items():
        views[name] = {"image": f"{name}.tif", "pixel_size_m": v.pixel_size_m,
                       "along_track_angle_deg": v.along_track_angle_deg,
                       "map_to_image": v.map_to_image.coeffs()}
    doc = {"format": "prismstation-scene/1", "crs": scene.crs,
           "satellite_altitude_m": scene.satellite_altitude_m,
           "ground_track": scene.track.points.tolist(), "views": views}
    if geoid is not None:
        doc["geoid_undulation_m"] = geoid
    (tmp_path / "scene.json").write_text(json.dumps(doc, indent=1))
    with open(tmp_path / "points.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "E", "N", "H", "kind", "height"])
        for p in pts:
            if p.ground is not None:
                H = p.ground[2] - (geoid if ortho else 0)
                w.writerow([p.id, p.ground[0], p.ground[1], H, p.kind, "orthometric" if ortho else "ellipsoidal"])
    with open(tmp_path / "measurements.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "view", "x", "y"])
        for p in pts:
            for v, (x, y) in p.image.items():
                w.writerow([p.id, v, x, y])


@pytest.mark.parametrize("heading,path_oriented", [(192, True), (348, False)])
def test_new_fit_json(tmp_path, heading, path_oriented, capsys):
    sc = make_scene(heading, path_oriented)
    pts = make_points(sc, noise_px=0.3, seed=11)
    write_triplet(tmp_path, sc, pts, geoid=55.0, ortho=True)
    proj = tmp_path / "t.prismproj"
    assert main(["new", str(proj), "--scene", str(tmp_path / "scene.json"),
                 "--points", str(tmp_path / "points.csv"),
                 "--measurements", str(tmp_path / "measurements.csv")]) == 0
    out = tmp_path / "fit.json"
    assert main(["fit", str(proj), "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert "Table 1" in capsys.readouterr().out
    icp = [p for p in rep["points"] if p["kind"] == "ICP"]
    assert len(icp) == 41
    truth = {p.id: p.ground for p in pts}
    dE = [p["E_est"] - truth[p["id"]][0] for p in icp]
    dh = [p["h_est"] - truth[p["id"]][2] for p in icp]
    # 0.3 px at 2.5 m: planimetry ~0.9 m per axis; height from F−B parallax ~ 2.5·0.42 ≈ 1.1 m
    assert math.sqrt(np.mean(np.square(dE))) < 1.5
    assert math.sqrt(np.mean(np.square(dh))) < 2.0
    st = rep["statistics"]
    assert st["image"]["N"]["ICP"]["px"]["x"]["n"] == 41
    assert rep["model"]["bias"]["N"]["parameters"]["B5"]["std"] > 0


def test_bad_input_exits_2_with_one_line(tmp_path, capsys):
    sc = make_scene()
    pts = make_points(sc, n_gcp=3, n_icp=2)
    write_triplet(tmp_path, sc, pts)
    with open(tmp_path / "measurements.csv", "a") as fh:
        fh.write("P99,N,12.5,notanumber\n")
    rc = main(["new", str(tmp_path / "x.prismproj"), "--scene", str(tmp_path / "scene.json"),
               "--measurements", str(tmp_path / "measurements.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "measurements.csv, line 17" in err[0] and "'notanumber' is not a number" in err[0]


def test_scene_field_errors_name_the_field(tmp_path, capsys):
    sc = make_scene()
    write_triplet(tmp_path, sc, make_points(sc, n_gcp=3, n_icp=0))
    doc = json.loads((tmp_path / "scene.json").read_text())
    doc["views"]["F"]["pixel_size_m"] = "2.5m"
    (tmp_path / "scene.json").write_text(json.dumps(doc, indent=1))
    rc = main(["new", str(tmp_path / "y.prismproj"), "--scene", str(tmp_path / "scene.json")])
    err = capsys.readouterr().err
    assert rc == 2 and "views.F.pixel_size_m" in err and "line" in err


def test_fit_with_too_few_gcps_exits_2(tmp_path, capsys):
    sc = make_scene()
    write_triplet(tmp_path, sc, make_points(sc, n_gcp=2, n_icp=3))
    proj = tmp_path / "z.prismproj"
    main(["new", str(proj), "--scene", str(tmp_path / "scene.json"), "--points", str(tmp_path / "points.csv"),
          "--measurements", str(tmp_path / "measurements.csv")])
    assert main(["fit", str(proj)]) == 2
    assert "at least 3 GCPs" in capsys.readouterr().err
    assert main(["fit", str(proj), "--bias", "shift"]) == 0


def test_a_reader_that_stops_early_ends_the_command_quietly(tmp_path):
    """`prismstation fit p | head -0`: the pipe closes under the report; the command ends with
    the shell's status for SIGPIPE (141), prints nothing more and logs no crash (it did: a
    traceback in the state folder and a line naming a broken pipe as the command's error)."""
    import os
    import subprocess
    from pathlib import Path
    import sys
    from prismstation.sim.small_project import make_project
    proj = make_project(tmp_path / "p", images=False).path
    env = {**os.environ, "XDG_STATE_HOME": str(tmp_path / "state")}
    proc = subprocess.Popen([str(Path(sys.executable).with_name("prismstation")), "fit", str(proj)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc.stdout.close()                       # the reader goes away before the report is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and err == "", err
    assert not (tmp_path / "state").exists() or not any((tmp_path / "state").rglob("crash-*"))
