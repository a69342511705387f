"""ICP accuracy of the empirical model on rigorous simulated triplets.

Prints, per geometry and over several seeds, the ICP RMSE per axis in image pixels (N view)
and on the ground (E, N, h metres), beside the noise floors. Usage:
    python benchmarks/accuracy.py [--seeds 3] [--size 1000]
"""
import argparse
import json
import math
import tempfile
from pathlib import Path

import numpy as np

from prismstation.ops.project import create
from prismstation.io.report import report_dict
from prismstation.ops.fit import solve_project
from prismstation.sim import simulate

CASES = {"1B2-R descending": {}, "1B2-R ascending": {"ascending": True},
         "1B2-G descending": {"north_up": True}, "1B2-G ascending": {"north_up": True, "ascending": True}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--size", type=int, default=1000)
    ap.add_argument("--noise", type=float, default=0.3)
    a = ap.parse_args()
    floor_px = a.noise * math.sqrt(1 + 3 / 9)
    floor_h = 2.4962 * a.noise * math.sqrt(2) * math.sqrt(1 + 2 / 9)
    print(f"9 GCP, 41 ICP, {a.noise} px noise, no survey noise, {a.size} px images, {a.seeds} seeds")
    print(f"floors: image {floor_px:.3f} px per axis ({floor_px * 2.5:.2f} m), height {floor_h:.2f} m")
    print(f"{'geometry':<18}{'x px':>8}{'y px':>8}{'E m':>8}{'N m':>8}{'plan m':>8}{'h m':>8}")
    for name, kw in CASES.items():
        acc = {k: [] for k in ("x", "y", "E", "N", "h")}
        for seed in range(a.seeds):
            with tempfile.TemporaryDirectory() as d:
                d = Path(d)
                simulate(d, size=a.size, seed=100 + seed, noise_px=a.noise, survey_sigma_xy=0,
                         survey_sigma_h=0, **kw)
                proj = create(d / "p.prismproj", d / "scene.json", d / "points.csv", d / "measurements.csv")
                rep = report_dict(solve_project(proj))
                truth = {p["id"]: p for p in json.loads((d / "truth.json").read_text())["points"]}
            for p in rep["points"]:
                if p["kind"] == "ICP":
                    t = truth[p["id"]]
                    acc["x"].append(p["residual_px"]["N"][0]); acc["y"].append(p["residual_px"]["N"][1])
                    acc["E"].append(p["E_est"] - t["E"]); acc["N"].append(p["N_est"] - t["N"])
                    acc["h"].append(p["h_est"] - t["h"])
        r = {k: math.sqrt(np.mean(np.square(v))) for k, v in acc.items()}
        print(f"{name:<18}{r['x']:>8.3f}{r['y']:>8.3f}{r['E']:>8.2f}{r['N']:>8.2f}"
              f"{math.hypot(r['E'], r['N']):>8.2f}{r['h']:>8.2f}")


if __name__ == "__main__":
    main()
