"""The matcher's σ calibration (:mod:`prismstation.core.matching.matching`): empirical scatter against
formal and claimed σ on real independent imagery (Pléiades triplet closure, no truth needed)
and on a simulated PRISM triplet with relief (known truth).

Run: ``PYTHONPATH=src:. .venv/bin/python benchmarks/match_sigma.py [SIM_DIR] [N_POINTS]``
(SIM_DIR: a ``prismstation simulate`` output, default one made in a temporary folder).
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.sigma_experiments import closure_rows, summary, truth_rows

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "pleiades_triplet"


def show(name, s) -> None:
    np.set_printoptions(precision=3, suppress=True)
    print(f"{name}: n {s['n']}, RMS error x/y {s['rms_err']} px")
    for k in ("formal", "claimed"):
        print(f"  {k:8s} RMS z x/y {s[f'rms_z_{k}']}, inside the 95 % ellipse {100 * s[f'in95_{k}']:.1f} %")


def main() -> None:
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 400
    show("Pléiades triplet closure (1→2→3 − 1→3)", summary(closure_rows(DATA, n=n)))
    sim = sys.argv[1] if len(sys.argv) > 1 else None
    if sim is None:
        from prismstation.sim import simulate
        sim = tempfile.mkdtemp(prefix="match-sigma-")
        simulate(sim, size=2000, seed=2008)
    show("simulated PRISM triplet, truth", summary(truth_rows(sim)))


if __name__ == "__main__":
    main()
