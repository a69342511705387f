"""Orientation without GCPs of one scene against several reference DEMs: where each puts it.

    python benchmarks/orient_references.py SCENE_DIR REF.tif [REF.tif ...] [--patch-km 2]

``SCENE_DIR`` holds ``scene.json``, ``points.csv``, ``measurements.csv`` and a truth: the
simulator's ``truth.json`` (``points``: id, E, N, h) or ``{id: [E, N, h, kind]}``. Every point
is taken as a check point (GCPs become ICPs: nothing but the reference controls the
orientation). Per reference: ``new`` (``--geoid``, default ``auto``: the EGM96 grid on PROJ's
paths, as SRTM's heights need) and ``orient-dem --json`` through the command line; printed: the
exit status, the verdict and the stated planimetric σ, the check points' mean error east and
north, their planimetric RMS, their mean height error and its RMS, the run time.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from prismstation.cli import main  # noqa: E402


def truth_points(scene_dir: Path) -> dict:
    """id → (E, N, h) from either truth format."""
    t = json.loads((scene_dir / "truth.json").read_text())
    if isinstance(t, dict) and isinstance(t.get("points"), list):
        return {p["id"]: (p["E"], p["N"], p["h"]) for p in t["points"]}
    return {k: tuple(v[:3]) for k, v in t.items()}


def check_points_only(src: Path, dst: Path) -> None:
    with open(src, newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(dst, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({**r, "kind": "ICP" if r.get("kind") == "GCP" else r.get("kind")})


def orient(scene_dir: Path, ref: Path, work: Path, patch_km: float | None, geoid: str) -> dict:
    pts = work / "points.csv"
    check_points_only(scene_dir / "points.csv", pts)
    proj, out = work / "p.prismproj", work / "dem.json"
    err = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["new", str(proj), "--force", "--scene", str(scene_dir / "scene.json"),
                     "--points", str(pts), "--measurements", str(scene_dir / "measurements.csv"),
                     "--geoid", geoid])
        if code == 0:
            code = main(["orient-dem", str(proj), str(ref), "--json", str(out),
                         *(["--patch-km", str(patch_km)] if patch_km else [])])
    row = {"reference": ref.name, "exit": code, "seconds": time.perf_counter() - t0}
    if not out.exists():
        row["failure"] = (err.getvalue().strip().splitlines() or [f"exit {code}"])[-1]
        return row
    rep = json.loads(out.read_text())
    truth = truth_points(scene_dir)
    got = [p for p in rep["points"] if p["id"] in truth and p.get("E_est") is not None]
    d = np.array([[p["E_est"] - truth[p["id"]][0], p["N_est"] - truth[p["id"]][1],
                   p["h_est"] - truth[p["id"]][2]] for p in got])
    sg = rep["dem_control"].get("sigma_m") or {}
    row.update(points=len(got), verdict=rep["dem_control"]["verdict"]["status"],
               sigma_plan=float(np.hypot(sg.get("E") or np.nan, sg.get("N") or np.nan)),
               dE=float(d[:, 0].mean()), dN=float(d[:, 1].mean()),
               plan=float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))),
               dh=float(d[:, 2].mean()), height=float(np.sqrt(np.mean(d[:, 2] ** 2))))
    return row


def run(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene_dir", type=Path)
    ap.add_argument("references", type=Path, nargs="+")
    ap.add_argument("--patch-km", type=float, default=None, help="orient-dem --patch-km")
    ap.add_argument("--geoid", default="auto", help="new --geoid (default auto)")
    a = ap.parse_args(argv)
    print("| reference | exit | verdict | stated σ plan m | mean ΔE m | mean ΔN m | plan RMS m | "
          "mean Δh m | height RMS m | points | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for ref in a.references:
        with tempfile.TemporaryDirectory(prefix="orient_ref_") as tmp:
            r = orient(a.scene_dir, ref, Path(tmp), a.patch_km, a.geoid)
        rows.append(r)
        if "failure" in r:
            print(f"| {r['reference']} | {r['exit']} | {r['failure']} | | | | | | | | {r['seconds']:.0f} |",
                  flush=True)
            continue
        print(f"| {r['reference']} | {r['exit']} | {r['verdict']} | {r['sigma_plan']:.1f} | "
              f"{r['dE']:+.2f} | {r['dN']:+.2f} | {r['plan']:.2f} | {r['dh']:+.2f} | "
              f"{r['height']:.2f} | {r['points']} | {r['seconds']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(run())
