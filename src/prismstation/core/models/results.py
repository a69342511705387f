"""A fit's results per point: :class:`PointResult` (one point) and :class:`PointColumns`
(every point, as arrays over the points).

A fit computes its results vectorised; :class:`PointColumns` keeps them so. The window reads
the arrays at every click (the plots, the residual vectors, the blunders); a
:class:`PointResult` is made only for a point asked for (:meth:`PointColumns.result`), or for
all of them at once (:meth:`PointColumns.results`: reports, the command line).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class PointResult:
    """Everything computed for one point. Residuals are measured − predicted (pixels);
    ``ground_residual`` is estimated − known (E, N, h metres); ``ground_sigma`` the
    estimate's σ (E, N, h metres) where the model states one."""

    id: str
    kind: str
    measured: dict
    predicted: dict
    residual_px: dict
    parallax_px: float | None
    across_px: dict               # 'F', 'B' -> across-track difference to N (pixels)
    ground_est: tuple[float, float, float] | None
    height_source: str | None     # 'parallax', 'reference', 'mean'
    ground_residual: tuple[float, float, float] | None
    std_residual: float | None    # largest |standardised residual| of this GCP, normal scale
    redundancy: float | None      # smallest redundancy number of its N observations
    blunder: bool = False
    note: str = ""
    ground_sigma: tuple | None = None


def rows_array(rows: list, width: int) -> np.ndarray:
    """``(len(rows), width)`` float array of a list of tuples (np.array is ~4× slower on
    tuples; every fit gathers the points' coordinates so)."""
    return np.fromiter(itertools.chain.from_iterable(rows), float, len(rows) * width).reshape(-1, width)


@dataclass(frozen=True, eq=False)
class PointColumns:
    """The results of ``n`` points, row ``i`` the ``i``-th point of the fit. NaN (a NaN row)
    where a point has no value: a view that does not measure it, no estimate, not a GCP.

    ``measured``, ``predicted``, ``residual``: view → ``(n, 2)`` image pixels; ``parallax``
    ``(n,)`` F−B parallax px; ``across``: 'F', 'B' → ``(n,)`` px (triplets); ``ground_est``,
    ``ground_residual``, ``ground_sigma`` ``(n, 3)`` E, N, h metres; ``std_residual``,
    ``redundancy`` ``(n,)``; ``blunder`` ``(n,)`` bool; ``ids``, ``kinds``, ``height_source``
    (None where no estimate), ``notes``: tuples of ``n``."""

    ids: tuple
    kinds: tuple
    measured: dict
    predicted: dict
    residual: dict
    parallax: np.ndarray
    across: dict
    ground_est: np.ndarray
    height_source: tuple
    ground_residual: np.ndarray
    std_residual: np.ndarray
    redundancy: np.ndarray
    blunder: np.ndarray
    notes: tuple
    ground_sigma: np.ndarray | None = None
    _made: dict = field(default_factory=dict, repr=False)  # cache: 'rows', 'index', 'all'

    def __len__(self) -> int:
        return len(self.ids)

    @classmethod
    def of(cls, results, views) -> "PointColumns":
        """The columns of :class:`PointResult` ``results`` (their own objects are kept: the
        results read back are these)."""
        results = list(results)

        nan2, nan3 = (math.nan,) * 2, (math.nan,) * 3

        def pairs(attr, keys):
            return {v: rows_array([getattr(r, attr).get(v, nan2) for r in results], 2) for v in keys}

        def rows(attr):
            return rows_array([nan3 if getattr(r, attr) is None else getattr(r, attr) for r in results], 3)

        def scalars(attr):
            return np.array([math.nan if getattr(r, attr) is None else getattr(r, attr) for r in results], float)

        across_keys = sorted({v for r in results for v in r.across_px})
        across = {v: np.array([r.across_px.get(v, math.nan) for r in results], float) for v in across_keys}
        cols = cls(tuple(r.id for r in results), tuple(r.kind for r in results),
                   pairs("measured", views), pairs("predicted", views), pairs("residual_px", views),
                   scalars("parallax_px"), across, rows("ground_est"),
                   tuple(r.height_source for r in results), rows("ground_residual"),
                   scalars("std_residual"), scalars("redundancy"),
                   np.array([bool(r.blunder) for r in results], bool), tuple(r.note for r in results),
                   rows("ground_sigma") if any(r.ground_sigma is not None for r in results) else None)
        cols._made["all"] = tuple(results)
        return cols

    def measured_anywhere(self) -> np.ndarray:
        """``(n,)`` True where the point is measured in at least one view."""
        out = np.zeros(len(self.ids), bool)
        for a in self.measured.values():
            out |= np.isfinite(a[:, 0]) & np.isfinite(a[:, 1])
        return out

    def blunder_ids(self) -> tuple:
        """The ids of the points flagged as blunders, in the fit's order."""
        return tuple(self.ids[i] for i in np.flatnonzero(self.blunder).tolist())

    def index(self, pid: str) -> int | None:
        """The row of point ``pid`` (None: not in the fit)."""
        ix = self._made.get("index")
        if ix is None:
            ix = self._made["index"] = {p: i for i, p in enumerate(self.ids)}
        return ix.get(pid)

    def result(self, pid: str) -> PointResult | None:
        """The :class:`PointResult` of ``pid`` (None: not in the fit)."""
        i = self.index(pid)
        return None if i is None else self.results()[i] if "all" in self._made else self._row(i)

    def results(self) -> tuple:
        """Every point's :class:`PointResult`, in the fit's order (made once)."""
        out = self._made.get("all")
        if out is None:
            out = self._made["all"] = tuple(self._row(i) for i in range(len(self.ids)))
        return out

    def _row(self, i: int) -> PointResult:
        """Row ``i`` as a :class:`PointResult`, read from plain lists (element access to numpy
        arrays costs several times as much); the lists are made once."""
        rows = self._made.get("rows")
        if rows is None:
            rows = self._made["rows"] = self._lists()
        cache = rows["made"]
        r = cache.get(i)
        if r is not None:
            return r
        est = rows["est"][i]
        est = tuple(est) if math.isfinite(est[0]) and math.isfinite(est[1]) and math.isfinite(est[2]) else None
        g_res = rows["g_res"][i]
        g_res = tuple(g_res) if est is not None and not math.isnan(g_res[0]) else None
        sig = rows["sig"][i] if rows["sig"] is not None else None
        sig = tuple(sig) if est is not None and sig is not None and all(map(math.isfinite, sig)) else None
        py, s, red = rows["py"][i], rows["std"][i], rows["red"][i]
        r = cache[i] = PointResult(
            self.ids[i], self.kinds[i], _present(rows["measured"], i), _present(rows["predicted"], i),
            _present(rows["residual"], i), py if math.isfinite(py) else None,
            {v: a[i] for v, a in rows["across"].items() if math.isfinite(a[i])}, est,
            self.height_source[i] if est is not None else None, g_res,
            s if math.isfinite(s) else None, red if math.isfinite(red) else None,
            rows["blunder"][i], self.notes[i], sig)
        return r

    def _lists(self) -> dict:
        def pairs(d):
            return {v: list(zip(*a.T.tolist())) for v, a in d.items()}
        return {"measured": pairs(self.measured), "predicted": pairs(self.predicted),
                "residual": pairs(self.residual), "across": {v: a.tolist() for v, a in self.across.items()},
                "est": self.ground_est.tolist(), "g_res": self.ground_residual.tolist(),
                "sig": None if self.ground_sigma is None else self.ground_sigma.tolist(),
                "py": self.parallax.tolist(), "std": self.std_residual.tolist(),
                "red": self.redundancy.tolist(), "blunder": self.blunder.tolist(), "made": {}}


def _present(by_view: dict, i: int) -> dict:
    """``{view: (x, y)}`` of the views where row ``i`` has finite values."""
    out = {}
    for v, col in by_view.items():
        xy = col[i]
        if math.isfinite(xy[0]) and math.isfinite(xy[1]):
            out[v] = xy
    return out
