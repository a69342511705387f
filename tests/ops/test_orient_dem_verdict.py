"""orient-dem says when its result is not to be trusted: exit status 3, one
line on stderr, the verdict in the JSON; and a clear error when the views cannot be found."""
import json

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
