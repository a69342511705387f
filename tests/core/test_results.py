"""A fit's columns and the PointResults read from them: a result asked for alone equals the
one in the full list; columns made from results give those results back."""
import dataclasses
import math

import numpy as np

from prismstation.core.models.results import PointColumns
from prismstation.core.models.solution import solve
from tests.core.test_solve_reference import _project


def _same(a, b) -> bool:
    """Two PointResults equal field by field (NaN equal to NaN)."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
            continue
        if x != y:
            return False
    return True


def test_a_result_asked_alone_equals_the_one_in_the_list():
    sc, pts = _project()
    alone = solve(sc, pts)
    whole = solve(sc, pts)
    for p in pts:
        r = alone.point(p.id)          # made on its own, before any full list
        assert r is alone.point(p.id)  # (made once)
        assert _same(r, whole.points[[q.id for q in pts].index(p.id)])
    assert alone.point("nowhere") is None
    assert [r.id for r in whole.points] == [p.id for p in pts]
    c = whole.columns
    assert len(c) == len(pts) and c.blunder_ids() == tuple(r.id for r in whole.points if r.blunder)
    assert c.blunder_ids(), "the set has a blunder: nothing proved"
    np.testing.assert_array_equal(c.measured_anywhere(), [bool(r.measured) for r in whole.points])


def test_columns_of_results_give_them_back():
    sc, pts = _project()
    sol = solve(sc, pts)
    results = sol.points
    cols = PointColumns.of(results, sc.views)
    assert cols.results() == results and cols.result(results[3].id) is results[3]
    for v in sc.views:
        np.testing.assert_array_equal(cols.residual[v], sol.columns.residual[v])
        np.testing.assert_array_equal(cols.predicted[v], sol.columns.predicted[v])
    np.testing.assert_array_equal(cols.std_residual, sol.columns.std_residual)
    np.testing.assert_array_equal(cols.blunder, sol.columns.blunder)
    assert np.allclose(cols.ground_residual, sol.columns.ground_residual, equal_nan=True)

