"""The user guide's figures are the demo's: every number docs/guide.md quotes in §1 and §4 is
computed here from the demo project as ``prismstation demo`` makes it, formatted as the guide
writes it, and looked for in the guide's text. When the demo (the simulator, the engine) changes,
this fails and names the figures to write."""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
import rasterio

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide.md"


def _f(v: float, spec: str) -> str:
    """``format(v, spec)`` with the guide's minus sign (U+2212)."""
    return format(v, spec).replace("-", "−")


def section(text: str, number: int) -> str:
    """Section ``## number.`` of the guide, up to the next one."""
    m = re.search(rf"^## {number}\..*?(?=^## {number + 1}\.|\Z)", text, re.S | re.M)
    assert m, f"no section {number} in the guide"
    return m.group(0)


def demo_figures(project_path) -> dict:
    """``{section: [snippet, ...]}``: the figures of the demo as the guide writes them."""
    from prismstation.core.models.prism import theoretical_c1
    from prismstation.io.project import load_project
    from prismstation.ops.fit import solve_project

    project = load_project(project_path)
    sol = solve_project(project)
    kinds = [p.kind for p in project.points.values()]
    s1 = [f"with {kinds.count('GCP')} GCPs, {kinds.count('ICP')} independent check points (ICPs) "
          f"and {kinds.count('TIE')} tie points"]
    with rasterio.open(Path(project_path).parent / "triplet" / "truth_dem.tif") as dem:
        h = dem.read(1, masked=True)
    s1.append(f"hilly terrain ({float(h.min()):.0f}–{round(float(h.max()), -1):.0f} m)")

    n = sol.bias["N"]
    s4 = [f"| B{i + 1} | {_f(p, '+.6f')} | {_f(sd, '.2g')} |" for i, (p, sd) in enumerate(zip(n.params[:4], n.std[:4]))]
    s4 += [f"| B{i + 5} | {_f(p, '+.2f')} px | {_f(sd, '.1f')} |" for i, (p, sd) in enumerate(zip(n.params[4:], n.std[4:]))]
    s4.append(f"σ0 = {n.sigma0:.3f} (a-priori σ {sol.settings.sigma_px:g} px, so σ0 reads in pixels), "
              f"{n.lsq.dof} degrees of freedom")
    st = sol.stats
    g, i = st["image"]["N"]["GCP"]["m"], st["image"]["N"]["ICP"]["m"]
    s4.append(f"GCP RMS Rx {g.x.rms:.2f}, Ry {g.y.rms:.2f}; ICP RMS Rx {i.x.rms:.2f}, Ry {i.y.rms:.2f}; "
              f"planimetric RMS at the {i.x.n} ICPs **{i.planimetric_rms:.2f} m**")
    fn, bn = st["F-N"], st["B-N"]
    s4.append(f"F − N has mean **{_f(fn.mean, '.2f')} px** (sd {fn.std:.2f}) and B − N "
              f"**{_f(bn.mean, '.2f')} px** (sd {bn.std:.2f})")
    par = sol.model.parallax
    views = sol.scene.views
    s4.append(f"`h = {_f(par.c0, '.2f')} + {par.c1:.4f}·py` (theoretical c1 = {theoretical_c1(sol.scene):.4f} "
              f"for {views['F'].along_track_angle_deg:.1f}° and {views['B'].along_track_angle_deg:.1f}°")
    h = st["height"]
    s4.append(f"GCP RMS {h['GCP'].rms:.2f} m, ICP RMS **{h['ICP'].rms:.2f} m**")
    # the blunder exercise: G04 dragged five pixels in N
    before = sol.point("G04").std_residual
    m = project.measurements[("G04", "N")]
    project.set_measurement(dataclasses.replace(m, x=m.x + 5.0))
    moved = solve_project(project)
    r = moved.point("G04")
    assert r.blunder and [p.id for p in moved.points if p.blunder] == ["G04"]
    s4.append(f"its standardised residual goes from {before:.2f} to {r.std_residual:.2f}")
    s4.append(f"above the threshold {sol.settings.blunder_threshold:.2f}")
    return {1: s1, 4: s4}


@pytest.mark.slow
def test_the_guides_figures_are_the_demos(real_demo_master):
    text = GUIDE.read_text(encoding="utf-8")
    missing = [(n, s) for n, snippets in demo_figures(real_demo_master).items()
               for s in snippets if s not in section(text, n)]
    assert not missing, "docs/guide.md no longer quotes the demo; write these:\n" + "\n".join(
        f"  §{n}: {s}" for n, s in missing)
