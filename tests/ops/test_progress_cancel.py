"""Every operation of ops/ reports progress through the one protocol, and a cancel (the
progress callable returning False) raises Cancelled and leaves no output file."""
from dataclasses import replace

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.errors import Cancelled, InputError
from prismstation.io.dem import read_dem, write_dem
from prismstation.io.project import load_project
from prismstation.io.windows import ImageWindows
from prismstation.ops.fit import solve_project
from prismstation.ops.orient_dem import orient_from_dem
from prismstation.ops.progress import checkpoint, partial_output, scaled
from prismstation.ops.reference_heights import load_for_scene
from prismstation.ops.tie_points import auto_tie_points
from prismstation.ops.validate import validate_dsm_files
from prismstation.sim import simulate
from prismstation.sim.reference import make_reference_dem


class Recorder:
    """A progress callable that asks to stop once ``fraction`` reaches ``stop_at``."""

    def __init__(self, stop_at=2.0):
        self.stop_at, self.calls = stop_at, []

    def __call__(self, fraction, message=""):
        self.calls.append((fraction, message))
        return fraction < self.stop_at


@pytest.fixture(scope="module")
def triplet(tmp_path_factory):
    d = tmp_path_factory.mktemp("triplet")
    simulate(d, size=400, seed=5)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=1)
    assert main(["new", str(d / "p.prismproj"), "--scene", str(d / "scene.json"), "--points",
                 str(d / "points.csv"), "--measurements", str(d / "measurements.csv")]) == 0
    return d


def test_checkpoint_and_scaled():
    r = Recorder(stop_at=0.5)
    checkpoint(r, -0.3, "clamped")
    checkpoint(scaled(r, 0.2, 0.4), 0.5, "half of the sub-range")
    assert r.calls == [(0.0, "clamped"), (pytest.approx(0.3), "half of the sub-range")]
    checkpoint(None, 0.5)                       # no callable: nothing to report, never stops
    with pytest.raises(Cancelled):
        checkpoint(r, 1.7)                      # reported as 1.0, refused
    checkpoint(lambda f, m="": None, 0.6)       # None means go on


def test_partial_output_is_renamed_on_success_and_removed_on_error(tmp_path):
    tmp_path = tmp_path / "out"
    tmp_path.mkdir()
    out = tmp_path / "o.txt"
    out.write_text("old")
    with pytest.raises(Cancelled):
        with partial_output(out) as part:
            open(part, "w").write("half")
            raise Cancelled("stop")
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["o.txt"]
    with partial_output(out) as part:
        open(part, "w").write("new")
    assert out.read_text() == "new" and [p.name for p in tmp_path.iterdir()] == ["o.txt"]


def test_validation_reports_progress_and_a_cancel_writes_no_difference_raster(tmp_path):
    tmp_path = tmp_path / "out"
    tmp_path.mkdir()
    t = (30.0, 0.0, 500000.0, 0.0, -30.0, 4600000.0)
    h = np.add.outer(np.arange(40.0), np.arange(50.0))
    write_dem(tmp_path / "dsm.tif", h + 1.5, "EPSG:32631", t)
    write_dem(tmp_path / "ref.tif", h, "EPSG:32631", t)
    r = Recorder()
    v, info = validate_dsm_files(tmp_path / "dsm.tif", tmp_path / "ref.tif", diff_out=tmp_path / "d.tif",
                                 progress=r)
    assert v.overall.bias == pytest.approx(1.5) and read_dem(tmp_path / "d.tif").heights.shape == (40, 50)
    fractions = [f for f, _ in r.calls]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0 and len(fractions) >= 4
    for stop in fractions[:-1]:                 # a cancel at any step: no raster, no leftovers
        (tmp_path / "d.tif").unlink()
        with pytest.raises(Cancelled):
            validate_dsm_files(tmp_path / "dsm.tif", tmp_path / "ref.tif", diff_out=tmp_path / "d.tif",
                               progress=Recorder(stop_at=stop))
        assert sorted(p.name for p in tmp_path.iterdir()) == ["dsm.tif", "ref.tif"]
        write_dem(tmp_path / "d.tif", h, "EPSG:32631", t)


def test_orientation_from_a_dem_cancels_at_its_first_checkpoint(triplet):
    project = load_project(triplet / "p.prismproj")
    r = Recorder(stop_at=0.0)
    with pytest.raises(Cancelled):
        orient_from_dem(project, triplet / "srtm.tif", patch_m=500.0, progress=r)
    assert len(r.calls) == 1 and project.dem_control is None and project.revision == 0


def test_automatic_ties_report_each_point_and_cancel(triplet):
    project = load_project(triplet / "p.prismproj")
    sol = solve_project(project)
    r = Recorder()
    with ImageWindows(project.scene) as im:
        auto_tie_points(sol, im, grid=3, progress=r)
        assert [m for _, m in r.calls] == [f"point {k} of 9" for k in range(1, 10)]
        r = Recorder(stop_at=0.5)
        with pytest.raises(Cancelled):
            auto_tie_points(sol, im, grid=3, progress=r)
    assert max(f for f, _ in r.calls) >= 0.5 and len(r.calls) < 9


def test_reference_heights_cover_the_scene_and_cancel(triplet):
    project = load_project(triplet / "p.prismproj")
    heights = load_for_scene(triplet / "srtm.tif", project, progress=Recorder())
    n = project.scene.views["N"]
    centre = n.map_to_image.inverse()(np.array([[n.shape[1] / 2, n.shape[0] / 2]]))
    assert np.isfinite(heights(centre)).all()
    with pytest.raises(Cancelled):
        load_for_scene(triplet / "srtm.tif", project, progress=Recorder(stop_at=0.0))


def test_a_malformed_dem_control_record_is_an_input_error(triplet):
    project = load_project(triplet / "p.prismproj")
    with project.batch():
        project.set_dem_control({"patches": [{"window": [0, 0, 1, 1]}], "mean_height": 0.0})
        project.set_settings(replace(project.settings, orientation="dem"))
    with pytest.raises(InputError, match="dem_control"):
        solve_project(project)
