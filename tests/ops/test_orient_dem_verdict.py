"""orient-dem says when its result is not to be trusted: exit status 3, one
line on stderr, the verdict in the JSON; and a clear error when the views cannot be found."""
import json

import numpy as np
import pytest

from prismstation.cli import main
from prismstation.sim import simulate
from prismstation.sim.reference import make_reference_dem


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    d = tmp_path_factory.mktemp("verdict")
    simulate(d, size=1200, seed=7)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=1)
    proj = d / "p.prismproj"
    assert main(["new", str(proj), "--scene", str(d / "scene.json"), "--points", str(d / "points.csv"),
                 "--measurements", str(d / "measurements.csv")]) == 0
    return d, proj


@pytest.mark.slow  # ~25 s
def test_too_few_patches_exit_3_with_the_verdict(project, capsys):
    d, proj = project
    # 1.5 km patches on a 3 km scene: 4 patches, fewer than the 6 the χ² test needs
    code = main(["orient-dem", str(proj), str(d / "srtm.tif"), "--patch-km", "1.5",
                 "--geolocation-sigma-m", "30", "--json", str(d / "few.json")])
    err = capsys.readouterr().err
    assert code == 3 and "NOT TRUSTED (too_few)" in err
    rec = json.loads((d / "few.json").read_text())["dem_control"]
    assert rec["verdict"]["status"] == "too_few" and rec["sigma_apriori_m"] == 30.0
    assert rec["coarse"]["radius_px"] == pytest.approx(3 * 30 * 2 ** 0.5 / 2.5)
    # the matcher's pull toward its prior, common to every patch (their scatter never sees it),
    # is measured (the patches matched again with the prior moved) and is in the σ and the verdict
    pull = rec["adjustment"]["prior_pull"]
    assert pull["offset_px"] == 0.5 and len(pull["theta_change"]) == 9 and not pull["reason"]
    assert 0 < pull["sigma_m"]["plan"] <= rec["sigma_m"]["plan"]
    assert "pull toward its prior" in rec["verdict"]["message"]
    # the relative DEMs' own errors, one draw from the pair DEMs' disagreement, likewise
    pairs = rec["adjustment"]["pair_dems"]
    assert len(pairs["theta_change"]) == 9 and 0 < pairs["rms_m"] < 5 and not pairs["reason"]
    assert 0 < pairs["sigma_m"]["plan"] <= rec["sigma_m"]["plan"]
    assert "as the pair DEMs disagree" in rec["verdict"]["message"]
    # where the adjustment was started: run again from 30 m away east and north, its response
    start = rec["adjustment"]["start"]
    assert start["kick_m"] == 30.0 and start["start_sigma_m"] == 30.0 and not start["reason"]
    assert np.shape(start["k"]) == (2, 2) and np.shape(start["theta_change"]) == (2, 9)
    assert "where the adjustment was started" in rec["verdict"]["message"]


@pytest.mark.slow  # ~40 s: the whole orientation runs and the flat reference is refused (too_smooth)
def test_a_reference_of_other_terrain_is_an_error(project, tmp_path, capsys):
    import numpy as np
    import rasterio
    d, proj = project
    with rasterio.open(d / "srtm.tif") as src:
        prof, h = src.profile, src.read(1)
    other = tmp_path / "other.tif"
    with rasterio.open(other, "w", **prof) as dst:                 # the same grid, flat terrain
        dst.write(np.full_like(h, 300.0), 1)
    code = main(["orient-dem", str(proj), str(other), "--patch-km", "1"])
    err = capsys.readouterr().err
    assert code != 0 and "Traceback" not in err and err.strip(), err


@pytest.mark.slow  # ~40 s: a scene of its own
def test_flat_terrain_is_refused_with_the_reason(tmp_path, capsys):
    """Terrain with almost no relief (the simulator's smooth hills × 0.01: a few metres, under
    the reference's 2 m noise) fixes the height of the field but no horizontal shift: exit
    status 3, the verdict too_smooth naming both horizontal directions, what would help, the σ
    expected before the run already beyond the target, and a σ after it that covers the error
    (the reference's noisy gradients alone had stated 11 m for an error of 57 m)."""
    d = tmp_path
    simulate(d, size=1200, seed=7, terrain="smooth", relief_scale=0.01)
    make_reference_dem(d / "truth_dem.tif", d / "srtm.tif", seed=1)
    proj = d / "p.prismproj"
    assert main(["new", str(proj), "--scene", str(d / "scene.json"), "--points", str(d / "points.csv"),
                 "--measurements", str(d / "measurements.csv")]) == 0
    capsys.readouterr()
    code = main(["orient-dem", str(proj), str(d / "srtm.tif"), "--patch-km", "1", "--geolocation-sigma-m", "30",
                 "--json", str(d / "flat.json")])
    out, err = capsys.readouterr()
    # "too smooth" or, with σ at the a-priori level, "fixes no shift": in both directions
    assert code == 3 and "NOT TRUSTED (too_smooth)" in err and "in both horizontal directions" in err
    assert "what would help: GCPs" in out and "expected from the terrain before the run" in out
    rec = json.loads((d / "flat.json").read_text())["dem_control"]
    assert rec["verdict"]["status"] == "too_smooth" and rec["verdict"]["advice"]
    assert rec["expected_sigma_m"]["plan"] > 5.0 and rec["sigma_m"]["plan"] > 5.0
    assert rec["sigma_m"]["h"] < 2.0                      # the height it does fix
    rep = json.loads((d / "flat.json").read_text())
    truth = {p["id"]: p for p in json.loads((d / "truth.json").read_text())["points"]}
    pts = [p for p in rep["points"] if p["kind"] in ("GCP", "ICP") and p.get("E_est") is not None]
    err = [(p["E_est"] - truth[p["id"]]["E"]) ** 2 + (p["N_est"] - truth[p["id"]]["N"]) ** 2 for p in pts]
    assert (sum(err) / len(err)) ** 0.5 < 2.0 * rec["sigma_m"]["plan"]


@pytest.mark.parametrize("args, said", [
    (["--geolocation-sigma-m", "600"], "asks for a search of"),   # 3 σ wider than the 3 km scene
    (["--geolocation-sigma-m", "1e308"], "asks for a search of"),
    (["--geolocation-sigma-m", "inf"], "the a-priori geolocation σ must be a positive number"),
    (["--target-m", "inf"], "the target σ must be a positive number"),
    (["--patch-km", "nan"], "the patch size must be a positive number"),
])
def test_a_priori_values_out_of_range_are_refused_in_one_line(project, capsys, args, said):
    """A σ whose search the scene cannot hold, or a value that is not a finite positive number:
    one line naming it, exit 2 (they ended in "unexpected error": an array of negative size)."""
    d, proj = project
    code = main(["orient-dem", str(proj), str(d / "srtm.tif"), *args])
    err = capsys.readouterr().err
    assert code == 2 and said in err and "unexpected" not in err and "Traceback" not in err, err
