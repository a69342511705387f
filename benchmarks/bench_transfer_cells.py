"""orient-dem's relative DEM cells against least-squares matching at a scene's points (run by
``bench_transfer.py --orient-cells``; see its docstring and docs/matching.md)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from bench_transfer import load_for_scene, load_project, solve_project, transfer  # noqa: F401
from prismstation.io.windows import ImageWindows


def orient_cells(d: Path, f: int = 2, half_cells: int = 24) -> None:
    """The relative DEM cells of ``orient-dem`` at the scene's points: its dense F↔B matcher
    (``core.matching.dense.parallax_map`` as orient-dem runs it: F and B averaged f×f, 9 × 9 windows,
    the reference DEM's parallax as prior, ±3 σ of it searched) against least-squares matching
    of F and B from N (``ops.transfer``, full resolution, reference DEM), both against the
    simulator's exact F−B parallax. Both carry F and B into N space through the fitted model."""
    from prismstation.core.models import prism
    from prismstation.core.adjustment.affine import Affine2D
    from prismstation.core.matching.dense import parallax_map
    from prismstation.io.windows import scaling, shift
    project = load_project(d / "p.prismproj")
    sol = solve_project(project)
    sc = project.scene
    dem = load_for_scene(d / "srtm.tif", project)
    truth = json.loads((d / "truth.json").read_text())["points"]
    c1 = prism.theoretical_c1(sc)
    tanF, tanB = sc.views["F"].tan_theta, sc.views["B"].tan_theta
    # view image → N image through the fitted biases: only relief parallax is left along d
    bN = sol.bias["N"]
    to_n = {v: Affine2D(np.vstack([np.column_stack([np.eye(2) + bN.M, bN.b]), [0, 0, 1]])[:2])
            @ prism.to_nadir_space(sc, sc.views[v])
            @ Affine2D(np.vstack([np.column_stack([np.linalg.inv(np.eye(2) + sol.bias[v].M),
                                                   -np.linalg.inv(np.eye(2) + sol.bias[v].M) @ sol.bias[v].b]),
                                  [0, 0, 1]])[:2]) for v in "FB"}

    def py_of(xf, xb, xn):
        dd = prism.along_track_unit(sc, sc.views["N"].map_to_image.inverse()(xn))
        return float((to_n["F"](np.asarray(xf, float)) - to_n["B"](np.asarray(xb, float))) @ dd)

    err = {"dense": [], "lsm": []}
    n_valid = {"dense": 0, "lsm": 0}
    spent = {"dense": 0.0, "lsm": 0.0}
    cells = 0
    with ImageWindows(sc) as im:
        for p in truth:
            xn = np.asarray(p["image"]["N"], float)
            py_true = py_of(p["image"]["F"], p["image"]["B"], xn)
            dd = prism.along_track_unit(sc, sc.views["N"].map_to_image.inverse()(xn))
            wd = (int(xn[0] / f) - half_cells, int(xn[1] / f) - half_cells, 2 * half_cells, 2 * half_cells)
            gx, gy = np.meshgrid((np.arange(wd[0], wd[0] + wd[2]) + 0.5) * f, (np.arange(wd[1], wd[1] + wd[3]) + 0.5) * f)
            pts = np.column_stack([gx.ravel(), gy.ravel()])
            h = np.full(len(pts), sol.mean_height)
            for _ in range(4):
                en = sol.image_to_ground("N", pts, h)
                h = np.nan_to_num(dem(en), nan=sol.mean_height)
            # the prior: the reference DEM's parallax through the model, in the same frame
            en = sol.image_to_ground("N", pts, h)
            py_ref = ((to_n["F"](sol.ground_to_image("F", en, h)) - to_n["B"](sol.ground_to_image("B", en, h))) @ dd)
            prior = (py_ref / f).reshape(gx.shape).astype(np.float32)
            rms_slope = 0.5           # orient-dem: ±3 σ of the reference heights and N's error on the slope
            search = int(np.ceil(3 * np.hypot(10.0, 5.0 * rms_slope) / c1 / f)) + 1
            arrays, tn = {}, {}
            reach = float(np.abs(prior).max()) * f + (search + 20) * f      # as orient-dem reads
            for v in "FB":
                c = to_n[v].inverse()(np.array([[wd[0] * f - reach, wd[1] * f - reach],
                                                [(wd[0] + wd[2]) * f + reach, (wd[1] + wd[3]) * f + reach]], float))
                (a0, b0), (a1, b1) = c.min(0), c.max(0)
                arr, ac0, ar0 = im.read_reduced(v, a0, b0, a1 - a0, b1 - b0, f)
                arrays[v] = arr
                tn[v] = (scaling(1 / f) @ to_n[v] @ shift(ac0, ar0) @ scaling(f)).matrix
            t0 = time.process_time()
            pm = parallax_map(arrays["F"], arrays["B"], tn["F"], tn["B"], wd, dd, prior=prior,
                              search_range=search, half_window=4, n_weight=tanF / (tanF + tanB))
            spent["dense"] += time.process_time() - t0
            cells += pm.parallax.size
            k = (int(xn[1] / f) - wd[1], int(xn[0] / f) - wd[0])
            val = pm.parallax[k] * f
            if np.isfinite(val):
                n_valid["dense"] += 1
                err["dense"].append(val - py_true)
            t0 = time.process_time()
            tr = transfer(sol, im, "N", xn, height_of=dem)
            spent["lsm"] += time.process_time() - t0
            if tr["F"].ok and tr["B"].ok:
                n_valid["lsm"] += 1
                err["lsm"].append(py_of((tr["F"].x, tr["F"].y), (tr["B"].x, tr["B"].y), xn) - py_true)
    n = len(truth)
    print(f"\norient-dem's relative DEM cells at the {n} points of {d.name} (F−B parallax, N px; "
          f"{c1 * f:.1f} m of height per decimated px)")
    for m in ("dense", "lsm"):
        e = np.array(err[m])
        per = spent[m] / (cells if m == "dense" else n) * 1e3
        unit = "ms per cell" if m == "dense" else "ms per point (F and B)"
        label = "dense NCC 9×9 at 1/2" if m == "dense" else "least squares (ours)"
        print(f"  {label:<22} valid {n_valid[m]:3d}/{n}  RMS {np.sqrt(np.mean(e ** 2)):.3f} px "
              f"({c1 * np.sqrt(np.mean(e ** 2)):.2f} m)  mean {np.mean(e):+.3f} px  median |e| {np.median(np.abs(e)):.3f} px  "
              f"> 1 px: {int(np.sum(np.abs(e) > 1))}   CPU {per:.3f} {unit}")
