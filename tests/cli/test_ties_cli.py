"""Automatic tie points from the command line: ``new --images`` (by default) and ``ties``.

Always: a synthetic triplet over a known terrain (:mod:`tests.ops.rpc_synth`: 300 px images,
4 m pixels, B/H 0.15 and 0.3, cubic RPCs in the GeoTIFF tags), where every tie point can be
checked against the truth: the first image's lattice pixel, its ray met with the terrain
through the true RPC, seen in the others through theirs. Where the shared data are present
(marked slow): the real Pléiades triplet and the Réunion and Giza pairs.
"""
from __future__ import annotations

import json
import re

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.core.models.rpc_bias import metres_per_degree
from prismstation.errors import Cancelled
from prismstation.io.project import load_project
from prismstation.ops.tie_points import add_tie_points
from tests.cli.test_rpc_workflows import write_tagged
from tests.ops.rpc_synth import World, analytic_terrain, make_rpc, render
from tests.ops.test_rpc_dsm import GSD, LAT0, LON0, SIZE, TANS

SUMMARY = re.compile(r"tie points: (\d+) of (\d+) grid points added")


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """The triplet's images (true RPCs in their tags), the world and the RPCs."""
    d = tmp_path_factory.mktemp("ties")
    world = World(LON0, LAT0, analytic_terrain, extent_m=2400, texture_cell_m=2.0)
    rpcs, paths = [], []
    for k, t in enumerate(TANS):
        rpc = make_rpc(LON0, LAT0, gsd=GSD, size=SIZE, tan_along=t, h_off=400.0, h_scale=500.0, seed=k + 1)
        write_tagged(d / f"img{k}.tif", render(rpc, world, SIZE), rpc)
        rpcs.append(rpc)
        paths.append(d / f"img{k}.tif")
    return d, world, rpcs, paths


def true_positions(world, rpcs, xy):
    """Where the ground under the first image's pixels ``xy`` ``(n, 2)`` is seen in every image."""
    h = np.full(len(xy), 400.0)
    for _ in range(30):
        lon, lat = rpcs[0].localize(xy[:, 0], xy[:, 1], h)
        h = world.height(lon, lat)
    return [np.column_stack(r.project(lon, lat, h)) for r in rpcs]


def test_new_images_matches_tie_points_against_the_truth(synthetic, tmp_path, capsys):
    d, world, rpcs, paths = synthetic
    proj = tmp_path / "p.prismproj"
    assert main(["new", str(proj), "--images", *map(str, paths), "--grid", "4"]) == 0
    out = capsys.readouterr().out
    m = SUMMARY.search(out)
    assert m and int(m[2]) == 16 and int(m[1]) >= 12, out
    assert "fit (shift bias): σ0" in out and "tie-point residual RMS x/y px: img0" in out
    project = load_project(proj)
    ties = [p for p in project.points.values() if p.kind == "TIE"]
    assert len(ties) == int(m[1])
    src = np.array([[project.measurement(p.id, "img0").x, project.measurement(p.id, "img0").y] for p in ties])
    truth = true_positions(world, rpcs, src)
    z = []
    for k, v in enumerate(("img1", "img2"), 1):
        got = np.array([[project.measurement(p.id, v).x, project.measurement(p.id, v).y] for p in ties])
        sig = np.array([np.hypot(project.measurement(p.id, v).sigma_px, project.measurement(p.id, "img0").sigma_px)
                        for p in ties])
        err = np.hypot(*(got - truth[k]).T)
        assert err.max() < 0.5, (v, err)
        z.append(err / (np.sqrt(2) * sig))        # per axis, in units of each axis's σ
    rms_z = float(np.sqrt(np.mean(np.concatenate(z) ** 2)))
    assert 0.2 < rms_z < 2.0, rms_z                  # the stated σ: honest within a factor of 2
    # every measurement carries its σ, and the file holds numbers only
    assert all(0 < m.sigma_px < 0.5 for m in project.measurements.values())
    assert "NaN" not in proj.read_text()


def test_ties_on_an_existing_project_adds_only_new_points(synthetic, tmp_path, capsys):
    d, world, rpcs, paths = synthetic
    proj = tmp_path / "p.prismproj"
    assert main(["new", str(proj), "--images", *map(str, paths), "--no-ties"]) == 0
    assert not load_project(proj).points
    capsys.readouterr()
    assert main(["ties", str(proj), "--grid", "3"]) == 0
    first = load_project(proj)
    n1 = len(first.points)
    assert n1 >= 6 and int(SUMMARY.search(capsys.readouterr().out)[1]) == n1
    before = proj.read_bytes()
    assert main(["ties", str(proj), "--grid", "3"]) == 0          # the same lattice: nothing new
    assert "9 others measured already, not searched again" in capsys.readouterr().out
    assert proj.read_bytes() == before
    assert main(["ties", str(proj), "--grid", "4"]) == 0          # another lattice: more points
    second = load_project(proj)
    assert len(second.points) > n1 and set(first.points) < set(second.points)


def test_a_bad_grid_is_refused(synthetic, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["ties", str(tmp_path / "p.prismproj"), "--grid", "1"])
    assert e.value.code == 2 and "2 to 100" in capsys.readouterr().err


def test_ctrl_c_and_cancel_save_nothing(synthetic, tmp_path, capsys, monkeypatch):
    d, world, rpcs, paths = synthetic
    proj = tmp_path / "p.prismproj"
    assert main(["new", str(proj), "--images", *map(str, paths), "--no-ties"]) == 0
    before = proj.read_bytes()
    capsys.readouterr()
    import prismstation.cli.ties as ties_cli
    calls = []

    def interrupting(what=""):
        def progress(fraction, message=""):
            calls.append(message)
            if len(calls) == 3:
                raise KeyboardInterrupt
        return progress
    monkeypatch.setattr(ties_cli, "progress_printer", interrupting)
    assert main(["ties", str(proj), "--grid", "3"]) == 130
    assert capsys.readouterr().err.strip() == f"prismstation ties: interrupted: no tie point saved in {proj}"
    assert proj.read_bytes() == before and calls == ["point 1 of 4", "point 2 of 4", "point 3 of 4"]   # the first pass: 4 of the 9
    project = load_project(proj)
    with pytest.raises(Cancelled):
        add_tie_points(project, grid=3, progress=lambda f, m="": f < 0.5)
    assert not project.points and project.revision == 0


# ----------------------------------------------------------------- real images
REAL = {"triplet": [f"pleiades_triplet/img_0{i}.tif" for i in (1, 2, 3)],
        "reunion": ["pleiades_pair_reunion/img_01.tif", "pleiades_pair_reunion/img_02.tif"],
        "gizeh": ["pleiades_pair_gizeh/img1.tif", "pleiades_pair_gizeh/img2.tif"]}


@pytest.mark.slow   # ~10-20 s each on a busy 2-core machine
@pytest.mark.parametrize("block", list(REAL))
def test_real_blocks(shared_data, tmp_path, capsys, block):
    """``new --images`` (the triplet) or ``new --no-ties`` then ``ties`` (the pairs) on a 4 × 4
    lattice: most points found, their fit's residuals a tenth of a pixel."""
    images = [str(shared_data / f) for f in REAL[block]]
    proj = tmp_path / "p.prismproj"
    if block == "triplet":
        assert main(["new", str(proj), "--images", *images, "--grid", "4"]) == 0
    else:
        assert main(["new", str(proj), "--images", *images, "--no-ties"]) == 0
        assert main(["ties", str(proj), "--grid", "4"]) == 0
    out = capsys.readouterr().out
    m = SUMMARY.search(out)
    assert m and int(m[1]) >= 8, out
    rms = [float(a) for a in re.findall(r" (\d+\.\d+)/(?:\d+\.\d+)", out.split("residual RMS")[1])]
    rms += [float(b) for b in re.findall(r" \d+\.\d+/(\d+\.\d+)", out.split("residual RMS")[1])]
    assert rms and max(rms) < 0.2, out
    data = json.loads(proj.read_text())
    assert all(m.get("sigma_px", 0) > 0 for m in data["measurements"])


def test_ties_with_a_reference_dem(synthetic, tmp_path, capsys):
    """``--dem``: the searches around the reference's heights (here the true terrain); the
    points found as without it, against the truth."""
    from tests.ops.test_rpc_dsm import write_reference
    d, world, rpcs, paths = synthetic
    write_reference(tmp_path / "ref.tif", world)
    proj = tmp_path / "p.prismproj"
    assert main(["new", str(proj), "--images", *map(str, paths), "--no-ties"]) == 0
    assert main(["ties", str(proj), "--grid", "3", "--dem", str(tmp_path / "ref.tif")]) == 0
    project = load_project(proj)
    ties = list(project.points)
    assert len(ties) >= 6, capsys.readouterr().out
    src = np.array([[project.measurement(p, "img0").x, project.measurement(p, "img0").y] for p in ties])
    truth = true_positions(world, rpcs, src)
    got = np.array([[project.measurement(p, "img2").x, project.measurement(p, "img2").y] for p in ties])
    assert np.hypot(*(got - truth[2]).T).max() < 0.5
