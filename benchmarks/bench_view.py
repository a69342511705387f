"""Responsiveness of the large-image display.

Makes (once, cached) three full-size 14,000 × 16,000 uint8 textured GeoTIFFs (tiled 512, deflate,
overviews 2–64), opens three ImageViews side by side in an offscreen window, and prints:

- open → first paint: RasterSource open + set_source + a synchronous paint, one view and all three;
- pan/zoom frame time on the GUI thread (median, p95) over a scripted sequence of pans and zooms
  at scales from the whole image to 4 screen pixels per image pixel: per frame, the time to handle
  the pending events (tile deliveries included) and paint; tile reads run in worker threads;
- time until the full-resolution tiles of a new place are all shown after a jump (drive-to);
- resident memory (VmRSS) with the three views open after the sequence, and again after a long
  use (many places visited, tile caches full: they are bounded) and the window idle for 3 s.

The views are set up as the main window sets them up: GDAL's block cache bounded
(``io.raster.gdal_env``), tile caches of ``gui.views.TILE_CACHE_MB`` per source, glibc's heaps
limited and trimmed by the window's :class:`MemoryKeeper`.

Usage: ``python benchmarks/bench_view.py [--dir /tmp/prismstation_bench] [--frames N]``
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import numpy as np  # noqa: E402
import rasterio  # noqa: E402
from rasterio.enums import Resampling  # noqa: E402
from rasterio.transform import from_origin  # noqa: E402

WIDTH, HEIGHT = 14000, 16000
FRAME_BUDGET = 1 / 60


def make_image(path: Path, seed: int) -> None:
    """Textured uint8 GeoTIFF: a tiled smooth random texture plus large-scale gradients."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    tex = np.zeros((1024, 1024), np.float32)
    for sigma, amp in ((1.0, 0.6), (4.0, 1.0), (16.0, 1.5)):
        n = gaussian_filter(rng.standard_normal((1024, 1024)).astype(np.float32), sigma,
                            mode="wrap")
        tex += amp * n / n.std()
    tex = (tex - tex.mean()) / tex.std() * 25
    tmp = path.with_suffix(".part.tif")
    with rasterio.open(tmp, "w", driver="GTiff", width=WIDTH, height=HEIGHT, count=1,
                       dtype="uint8", tiled=True, blockxsize=512, blockysize=512,
                       compress="deflate", crs="EPSG:32629",
                       transform=from_origin(500000, 4600000, 2.5, 2.5)) as ds:
        cols = np.arange(WIDTH, dtype=np.float32)
        wide = np.tile(np.roll(tex, seed * 97, axis=1), (1, WIDTH // 1024 + 1))[:, :WIDTH]
        for r0 in range(0, HEIGHT, 512):
            rows = np.arange(r0, min(HEIGHT, r0 + 512), dtype=np.float32)
            strip = wide[rows.astype(int) % 1024]
            base = 110 + 50 * np.sin(cols / 2300.0)[None, :] + 40 * np.cos(rows / 1700.0)[:, None]
            ds.write(np.clip(base + strip, 0, 255).astype(np.uint8),
                     1, window=rasterio.windows.Window(0, r0, WIDTH, len(rows)))
        ds.build_overviews([2, 4, 8, 16, 32, 64], Resampling.average)
    tmp.rename(path)


def ensure_images(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"bench_{v}_{WIDTH}x{HEIGHT}.tif" for v in "NFB"]
    missing = [p for p in paths if not p.exists()]
    if missing:  # in a child process, so that its memory does not count in the figures
        t = time.perf_counter()
        subprocess.run([sys.executable, __file__, "--make-only", "--dir", str(folder)],
                       check=True)
        print(f"made {len(missing)} image(s) in {folder} in {time.perf_counter() - t:.1f} s")
    return paths


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def pct(values, q) -> float:
    return float(np.percentile(np.asarray(values) * 1000, q))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="/tmp/prismstation_bench", type=Path)
    ap.add_argument("--frames", type=int, default=40, help="frames per pan/zoom segment")
    ap.add_argument("--visits", type=int, default=60,
                    help="places visited by all three views for the long-use memory figure")
    ap.add_argument("--screenshot", type=Path, help="save a PNG of the window at the end")
    ap.add_argument("--make-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.make_only:
        args.dir.mkdir(parents=True, exist_ok=True)
        for i, v in enumerate("NFB"):
            p = args.dir / f"bench_{v}_{WIDTH}x{HEIGHT}.tif"
            if not p.exists():
                make_image(p, seed=i + 1)
        return 0
    paths = ensure_images(args.dir)

    from PySide6.QtCore import QPoint, QPointF, Qt
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication, QSplitter

    from prismstation.gui.image_view import ImageView
    from prismstation.gui.memory import MemoryKeeper
    from prismstation.gui.views import TILE_CACHE_MB
    from prismstation.io.raster import RasterSource

    app = QApplication.instance() or QApplication(sys.argv)
    keeper = MemoryKeeper(app)  # as the window's (before the tile readers' threads start)
    win = QSplitter()
    views = [ImageView() for _ in paths]
    for v in views:
        win.addWidget(v)
    win.resize(1920, 720)
    win.show()
    app.processEvents()
    rss0 = rss_mb()

    # ---- open -> first paint
    opens = []
    t_all = time.perf_counter()
    for v, p in zip(views, paths):
        t = time.perf_counter()
        v.set_source(RasterSource(p, cache_mb=TILE_CACHE_MB))
        v.graphics.viewport().repaint()
        opens.append(time.perf_counter() - t)
    t_all = time.perf_counter() - t_all

    cpu: list = []

    def wheel(vp, pos, delta) -> None:
        QApplication.sendEvent(vp, QWheelEvent(
            QPointF(pos), QPointF(vp.mapToGlobal(pos)), QPoint(0, 0), QPoint(0, delta),
            Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier,
            Qt.ScrollPhase.NoScrollPhase, False))

    def frame(active, event=None) -> float:
        """GUI-thread time of one event-loop turn: the input event (a mouse move or wheel step,
        delivered as Qt delivers it), pending events (tile deliveries) and the one paint of
        each view they scheduled."""
        t, c = time.perf_counter(), time.thread_time()
        if event is not None:
            event()
        app.processEvents()
        dt = time.perf_counter() - t
        cpu.append(time.thread_time() - c)  # the GUI thread's own CPU: insensitive to load
        time.sleep(max(0.0, FRAME_BUDGET - dt))  # the rest of a 60 Hz frame: workers read
        return dt

    def settle(timeout=10.0) -> float:
        t = time.perf_counter()
        while not all(v.tiles_complete() for v in views) and time.perf_counter() - t < timeout:
            app.processEvents()
            time.sleep(0.002)
        return time.perf_counter() - t

    settle()
    # ---- scripted pans and zooms, one view at a time (the operator's hand is in one view)
    rng = np.random.default_rng(0)
    times, per_scale = [], {}
    panned = 0.0  # screen pixels the drags moved the images, in all
    scales = [None, 16.0, 8.0, 4.0, 2.0, 1.0, 0.5, 0.25]  # None: fit (whole image)
    for k, s in enumerate(scales):
        v = views[k % 3]
        if s is None:
            v.fit()
        else:
            v.center_on(rng.uniform(2000, WIDTH - 2000), rng.uniform(2000, HEIGHT - 2000), s)
        frame([v])
        vp = v.graphics.viewport()
        c = QPoint(vp.width() // 2, vp.height() // 2)
        dx, dy = rng.uniform(-1, 1, 2)
        step = 25.0  # screen pixels per frame: a brisk drag
        seg = []
        left, none = Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier
        start = v.center()
        QTest.mousePress(vp, left, none, c)
        j = 0
        for i in range(args.frames):  # pan: a left-button drag, one mouse move a frame
            j += 1
            p = c + QPoint(int(dx * step * j), int(dy * step * j))
            if abs(p.x() - c.x()) > 250 or abs(p.y() - c.y()) > 250:  # re-grip at the centre
                def regrip(p=p):
                    QTest.mouseRelease(vp, left, none, p)
                    QTest.mousePress(vp, left, none, c)
                seg.append(frame([v], regrip))
                j = 0
                continue
            seg.append(frame([v], lambda p=p: QTest.mouseMove(vp, p)))
        QTest.mouseRelease(vp, left, none, p)
        end = v.center()
        panned += np.hypot(end[0] - start[0], end[1] - start[1]) / v.scale()
        for i in range(args.frames // 2):  # zoom in, then out, under the mouse: wheel steps
            delta = 120 if i < args.frames // 4 else -120
            seg.append(frame([v], lambda d=delta: wheel(vp, c, d)))
        per_scale["fit" if s is None else f"{s:g}"] = seg
        times += seg
    cpu_pan = list(cpu)

    # ---- drive-to: all three views jump to a new place at full resolution
    jumps, drive_frames = [], []
    n_cpu = len(cpu)
    for j in range(5):
        x, y = rng.uniform(1000, WIDTH - 1000), rng.uniform(1000, HEIGHT - 1000)
        t = time.perf_counter()
        for v in views:
            v.center_on(x, y, 1.0)
        drive_frames.append(frame(views))
        while not all(v.tiles_complete() for v in views) and time.perf_counter() - t < 10:
            drive_frames.append(frame(views))
        jumps.append(time.perf_counter() - t)
    cpu_drive = cpu[n_cpu:]
    settle()
    app.processEvents()
    rss = rss_mb()
    cache = sum(v.source.cache.nbytes for v in views) / 2**20

    # ---- a long session: many places at several scales, until the tile caches are full
    for j in range(args.visits):
        s = [1.0, 0.5, 2.0, 4.0][j % 4]
        x, y = rng.uniform(0, WIDTH), rng.uniform(0, HEIGHT)
        for v in views:
            v.center_on(x, y, s)
        frame(views)
        settle()
    idle_end = time.perf_counter() + 3.0  # the window idle: its memory keeper's turn
    while time.perf_counter() < idle_end:
        app.processEvents()
        time.sleep(0.01)
    rss_long = rss_mb()

    # ---- loupe: one cursor move = one small full-resolution read (or cached tiles) + paint
    from prismstation.gui.loupe import Loupe

    loupe = Loupe(zoom=8, pixels=25)
    loupe.attach(views[0])
    loupe.show()
    loupe_t = []
    for j in range(100):
        x, y = rng.uniform(0, WIDTH), rng.uniform(0, HEIGHT)
        t = time.perf_counter()
        views[0].cursor_moved.emit(x, y)
        loupe.repaint()
        loupe_t.append(time.perf_counter() - t)

    cache_long = sum(v.source.cache.nbytes for v in views) / 2**20

    print("prismstation ImageView benchmark: 3 x %d x %d uint8 GeoTIFF (tiled 512, deflate, "
          "overviews 2-64), window 1920 x 720 offscreen" % (WIDTH, HEIGHT))
    print(f"{'figure':46s} {'measured':>12s}   target")
    print(f"{'open -> first paint, one view (max of 3)':46s} {max(opens) * 1000:9.0f} ms   <= 500 ms")
    print(f"{'open -> first paint, all three views':46s} {t_all * 1000:9.0f} ms   <= 500 ms")
    print(f"{'pan/zoom frame, GUI thread, median':46s} {pct(times, 50):9.1f} ms   <= 16 ms")
    print(f"{'pan/zoom frame, GUI thread, p95':46s} {pct(times, 95):9.1f} ms   (report)")
    print(f"{'pan/zoom frame, GUI thread, max':46s} {pct(times, 100):9.1f} ms   (report)")
    print(f"{'pan/zoom frame, GUI-thread CPU, median / p95':46s} "
          f"{pct(cpu_pan, 50):5.1f} / {pct(cpu_pan, 95):4.1f} ms")
    print(f"{'machine load (1-min average, 2 cores here)':46s} {os.getloadavg()[0]:9.1f}")
    print(f"{'frames measured':46s} {len(times):12d}")
    print(f"{'distance dragged (real mouse events), screen px':46s} {panned:12.0f}")
    for name, seg in per_scale.items():
        print(f"{'  scale ' + name + ' img px/screen px: median / p95':46s} "
              f"{pct(seg, 50):5.1f} / {pct(seg, 95):4.1f} ms")
    print(f"{'drive-to, 3 views: frame median / p95':46s} "
          f"{pct(drive_frames, 50):5.1f} / {pct(drive_frames, 95):4.1f} ms")
    print(f"{'drive-to, 3 views: GUI-thread CPU median / p95':46s} "
          f"{pct(cpu_drive, 50):5.1f} / {pct(cpu_drive, 95):4.1f} ms")
    print(f"{'drive-to, 3 views: until full-res tiles shown':46s} "
          f"{np.median(jumps) * 1000:9.0f} ms   (median of {len(jumps)})")
    print(f"{'loupe update at a random place (uncached)':46s} "
          f"{pct(loupe_t, 50):5.1f} / {pct(loupe_t, 95):4.1f} ms (median / p95)")
    print(f"{'resident memory (VmRSS), three views open':46s} {rss:9.0f} MB   <= 500 MB")
    print(f"{'  of which before opening (Qt, numpy, ...)':46s} {rss0:9.0f} MB")
    print(f"{'  tile caches (3 sources)':46s} {cache:9.0f} MB")
    print(f"{f'resident memory after {args.visits} more places (long use)':46s} "
          f"{rss_long:9.0f} MB   <= 500 MB")
    print(f"{'  tile caches (3 sources, bounded)':46s} {cache_long:9.0f} MB")
    print(f"{'  heap handed back by the memory keeper':46s} {keeper.trims:9d} times")
    if args.screenshot:
        views[0].fit()
        views[1].center_on(WIDTH / 2, HEIGHT / 2, 4.0)
        views[2].center_on(WIDTH / 2, HEIGHT / 2, 0.5)
        settle()
        app.processEvents()
        win.grab().save(str(args.screenshot))
        print(f"screenshot: {args.screenshot}")
    ok = (max(opens) <= 0.5 and t_all <= 0.5 and pct(times, 50) <= 16 and rss <= 500
          and rss_long <= 500)
    print("all targets met" if ok else "SOME TARGETS MISSED")
    for v in views:
        v.close()
    return 0


if __name__ == "__main__":
    from prismstation.io.raster import gdal_env
    with gdal_env():  # an entry point: GDAL's block cache bounded as the window bounds it
        sys.exit(main())
