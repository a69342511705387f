"""The planimetric σ of stored ``orient-dem`` runs with today's view-offset term, beside the σ
they stated: for runs made before that term changed (``orient_sweep.py --keep DIR`` keeps each
case's ``dem_p*_s*.json`` beside its scene).

The offsets' term is added along track to the field's covariance at every lattice point, and
the planimetric σ is the RMS over the lattice, so replacing the term is exact:
``σ_new² = σ_stated² − s_then² + s_now²``, with ``s_then`` each view's offset σ taken whole
(the reference heights' 10 m in F's and B's offsets as if independent) and ``s_now``
:func:`prismstation.ops.orient_dem.offsets_along_sigma`. Printed per case: the check points'
planimetric RMSE, the σ stated and recomputed (each with the check points' own measurement
noise in quadrature), their ratios.

Run: ``.venv/bin/python benchmarks/orient_resigma.py DIR [DIR ...]``
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from prismstation.core.models import prism  # noqa: E402
from prismstation.io.scene import read_scene  # noqa: E402
from prismstation.core.orientation.view_offsets import SIGMA_HEIGHT_M  # noqa: E402
from prismstation.ops import orient_dem  # noqa: E402


def offsets_sigma_then(run, record: dict) -> float:
    """The term as the runs computed it (m): each view's combined σ, χ²-scaled, in quadrature."""
    rows, cols = run.shape
    N = run.scene.views["N"]
    en = prism.ancillary_to_ground(run.scene, N, np.array([[cols / 2, rows / 2]]), run.ref.mean_h)
    d = prism.along_track_unit(run.scene, en)[0]
    var = 0.0
    for v, w in (("F", 1.0 - run.n_weight), ("B", run.n_weight)):
        sx, sy = (float("nan") if c is None else float(c) for c in record["sigma_px"][v])
        vf = ((record.get("verdicts") or {}).get(v) or {}).get("variance_factor")
        var += w ** 2 * ((d[0] * sx) ** 2 + (d[1] * sy) ** 2) * (float(vf) if vf is not None else 1.0)
    return math.sqrt(var) * N.pixel_size_m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", type=Path, help="folders holding */e*/dem*.json (orient_sweep --keep)")
    a = ap.parse_args(argv)
    ratios = []
    print("| case | planimetric m | σ stated (error / σ) | σ now (error / σ) | offsets' term then → now m |")
    print("|---|---|---|---|---|")
    for f in sorted(p for d in a.dirs for p in d.glob("*/e*/dem*.json")):
        work, sim = f.parent, f.parent.parent
        rep = json.loads(f.read_text())
        dc = rep["dem_control"]
        scene = read_scene(work / "scene.json")
        run = orient_dem.OrientRun(scene, None, None, dc["sigma_apriori_m"], SIGMA_HEIGHT_M, 0.0, 1, None)
        run.ref = types.SimpleNamespace(mean_h=dc["mean_height"])
        then, now = offsets_sigma_then(run, dc["coarse"]), orient_dem.offsets_along_sigma(run, dc["coarse"])
        plan = math.hypot(dc["sigma_m"]["E"], dc["sigma_m"]["N"])
        plan_now = math.sqrt(max(plan ** 2 - then ** 2 + now ** 2, 0.0))
        t = json.loads((sim / "truth.json").read_text())
        truth = {p["id"]: p for p in t["points"]}
        pts = [p for p in rep["points"] if p["kind"] in ("GCP", "ICP") and p.get("E_est") is not None]
        dE = np.array([p["E_est"] - truth[p["id"]]["E"] for p in pts])
        dN = np.array([p["N_est"] - truth[p["id"]]["N"] for p in pts])
        err = math.hypot(math.sqrt(np.mean(dE ** 2)), math.sqrt(np.mean(dN ** 2)))
        meas = float(t["arguments"].get("noise_px", 0.0)) * scene.views["N"].pixel_size_m * math.sqrt(2)
        s_then, s_now = math.hypot(plan, meas), math.hypot(plan_now, meas)
        ratios.append(err / s_now)
        print(f"| {sim.name}/{work.name} | {err:.2f} | {s_then:.2f} ({err / s_then:.2f}) | "
              f"{s_now:.2f} ({err / s_now:.2f}) | {then:.2f} → {now:.2f} |")
    if ratios:
        print(f"\nerror / σ now: {min(ratios):.2f}–{max(ratios):.2f}, mean {np.mean(ratios):.2f} ({len(ratios)} cases)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
