"""Time and memory of the PDF report of a project with many points.

The report of a synthetic fit (53 points) with its points repeated under new ids up to N
points (the statistics stay those of the fit: only the document's size grows). Prints, for
each N, the seconds to make the PDF, its pages and size, and the process's peak memory. The
point tables list at most ``MAX_DOCUMENT_POINTS`` points (with a note); the figures use all.

    .venv/bin/python benchmarks/bench_report_large.py [N ...]   (default 5000 50000)
"""
from __future__ import annotations

import os
import resource
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_plots import solutions  # noqa: E402
from prismstation.gui.report_writer import write_document  # noqa: E402
from prismstation.io.report import report_dict  # noqa: E402


def grown(report: dict, n: int) -> dict:
    pts = report["points"]
    more = [dict(pts[i % len(pts)], id=f"X{i:06d}") for i in range(n)]
    return dict(report, points=more)


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [5000, 50000]
    rep = report_dict(solutions(12, 41)[0], project_path="synthetic.prismproj")
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            big = grown(rep, n)
            path = Path(tmp) / f"r{n}.pdf"
            t0 = time.perf_counter()
            write_document(big, path)
            dt = time.perf_counter() - t0
            pages = path.read_bytes().count(b"/Type /Page\n") or path.read_bytes().count(b"/Type /Page")
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            print(f"{n:6d} points: PDF in {dt:.1f} s, ~{pages} pages, {path.stat().st_size / 1024:.0f} KiB; "
                  f"peak memory so far {peak:.0f} MiB")


if __name__ == "__main__":
    main()
