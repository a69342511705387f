"""What an orientation from a reference DEM cannot check of its height datum: a project whose
constant geoid lies far from EGM96 reads an SRTM-like reference that far off, and the
orientation's heights with it (with a constant 0 m on a judged 10 km scene: trusted, its check
points 51.9 m off in height at a stated 1.1 m)."""
from __future__ import annotations

import shutil

import pytest
import rasterio

from prismstation.io.geoid import find_grid
from prismstation.ops.project import create
from prismstation.ops.reference_heights import DATUM_TOLERANCE_M, datum_note


@pytest.fixture()
def scene(foreign_data):
    if find_grid() is None:
        pytest.skip("no EGM96 grid on PROJ's data paths (packaging/setup.sh installs proj-data)")
    return foreign_data / "smooth_hills_10km"


@pytest.mark.parametrize("geoid, said", [("0", "read 56 m low"), ("auto", ""), ("56", ""),
                                         (str(56 - DATUM_TOLERANCE_M - 1), "read 6 m low"),
                                         ("120", "read 64 m high")])
def test_a_constant_geoid_far_from_egm96_is_named(scene, tmp_path, geoid, said):
    project = create(tmp_path / "p.prismproj", scene / "scene.json", geoid=geoid)
    note = datum_note(project, scene / "srtm_like.tif")
    if not said:
        assert note == ""
    else:
        assert note.startswith("not checked: the reference's height datum") and said in note, note
        assert "EGM96 lies 55.9 m above the ellipsoid" in note and "--geoid auto" in note


def test_a_reference_stating_ellipsoidal_heights_needs_no_geoid(scene, tmp_path):
    ref = tmp_path / "ellipsoidal.tif"
    shutil.copy(scene / "srtm_like.tif", ref)
    with rasterio.open(ref, "r+") as ds:
        ds.update_tags(HEIGHTS="ellipsoidal")
    project = create(tmp_path / "p.prismproj", scene / "scene.json", geoid="0")
    assert datum_note(project, ref) == ""
