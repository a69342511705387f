"""Time the recovery journal's share of an edit on the calling (GUI) thread: synchronous
(serialise + atomic write with fsync) against ``background=True`` (serialise, hand over).

The project is the 200-point one of benchmarks/bench_click.py (20 GCPs, 180 ICPs, 1500 px).
Each edit moves one measurement (``Project.set_measurement``: the journal is the only listener
of ``Project.changed``). Edits come ``--gap`` ms apart (a click rate; 0 = a burst). Prints the
median, 95th percentile and maximum in ms, and how many writes reached the disk.

    .venv/bin/python benchmarks/bench_journal.py [--dir DIR] [--edits 200] [--gap 20]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from prismstation.io.project import load_project, project_to_dict  # noqa: E402
from prismstation.io.recovery import Journal  # noqa: E402
from prismstation.model.points import Measurement  # noqa: E402
from prismstation.sim.small_project import make_project  # noqa: E402


class SerialiseOnly:
    """What the edit's call costs without any disk write (the floor of the background mode)."""

    writes = 0

    def __init__(self, project, path, background=None):
        self.project, self.path = project, path
        project.changed.connect(self.on_changed)

    def on_changed(self, revision):
        json.dumps(project_to_dict(self.project, self.path), ensure_ascii=False)

    def flush(self):
        pass

    def close(self):
        self.project.changed.disconnect(self.on_changed)

    def discard(self):
        pass


def run(path: Path, background, edits: int, gap_s: float) -> tuple[np.ndarray, int, float]:
    """``background``: False, True, or None (serialise only, nothing written)."""
    project = load_project(path)
    keys = sorted(project.measurements)
    journal = (SerialiseOnly if background is None else Journal)(project, path, background=background)
    times = []
    for k in range(edits):
        m = project.measurements[keys[k % len(keys)]]
        t0 = time.perf_counter()
        project.set_measurement(Measurement(m.id, m.view, m.x + 0.01, m.y, m.sigma_px))
        times.append(time.perf_counter() - t0)
        if gap_s:
            time.sleep(gap_s)
    t_flush = time.perf_counter()
    journal.flush()
    flush_ms = 1e3 * (time.perf_counter() - t_flush)
    writes = journal.writes
    journal.close()
    journal.discard()
    return 1e3 * np.array(times), writes, flush_ms


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", help="where the project and its journal go (default: a temp dir)")
    ap.add_argument("--edits", type=int, default=200)
    ap.add_argument("--gap", type=float, default=20.0, help="ms between edits (0: a burst)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        demo = make_project(Path(tmp), n_gcp=20, n_icp=180, size=1500, p=20.0, seed=9)
        project = load_project(demo.path)
        t0 = time.perf_counter()
        for _ in range(50):
            text = json.dumps(project_to_dict(project, demo.path), ensure_ascii=False)
        ser = 1e3 * (time.perf_counter() - t0) / 50
        print(f"project: {len(project.points)} points, {len(project.measurements)} measurements, "
              f"journal {len(text) / 1024:.0f} KiB; serialise (project_to_dict + json.dumps) "
              f"{ser:.2f} ms; disk: {demo.path.parent}")
        for gap in sorted({args.gap, 0.0}, reverse=True):
            for background in (False, True, None):
                t, writes, flush_ms = run(demo.path, background, args.edits, gap / 1e3)
                name = {False: "synchronous", True: "background ", None: "no write   "}[background]
                print(f"{name} gap {gap:4.0f} ms: changed handling on the calling thread "
                      f"median {np.median(t):.2f} ms, p95 {np.percentile(t, 95):.2f} ms, "
                      f"max {t.max():.2f} ms; {writes} writes for {args.edits} edits; "
                      f"final flush {flush_ms:.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
