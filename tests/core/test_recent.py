"""The recent-results memo of the fits: the same inputs give the object computed before,
different bytes compute again, and it forgets the oldest beyond its size."""
import numpy as np

from prismstation.core.models.prism_model import PrismModel
from prismstation.core.models.recent import Recent, key_of


def test_same_bytes_same_object_and_new_bytes_recompute():
    calls = []
    r = Recent(size=2)

    def compute(v):
        calls.append(v)
        return object()

    a = np.array([[1.0, 2.0]])
    first = r.get(key_of("bias", a), lambda: compute(1))
    assert r.get(key_of("bias", a.copy()), lambda: compute(2)) is first
    b = a.copy()
    b[0, 1] = np.nextafter(2.0, 3.0)  # one ulp: other bytes
    assert r.get(key_of("bias", b), lambda: compute(3)) is not first
    r.get(key_of("other"), lambda: compute(4))  # a third key: the oldest (a) is forgotten
    r.get(key_of("bias", a), lambda: compute(5))
    assert calls == [1, 3, 4, 5]


def test_key_tells_shapes_and_none_apart():
    assert key_of(np.zeros((2, 2))) != key_of(np.zeros(4))
    assert key_of(None) != key_of(0.0)
    assert key_of([0.5, 1.0]) == key_of(np.array([0.5, 1.0]))


def test_fit_with_memo_equals_fit_without():
    from tests.core.test_solve_reference import _project  # a full triplet with GCPs and ICPs

    scene, points = _project()
    recent = Recent()                                     # the caller's, not a module's
    memo = PrismModel.fit(scene, points, recent=recent)
    again = PrismModel.fit(scene, points, recent=recent)  # from the memo
    plain = PrismModel.fit(scene, points)                 # no memo: computed again
    other = PrismModel.fit(scene, points, recent=Recent())
    for v in scene.views:
        assert again.bias[v] is memo.bias[v] and plain.bias[v] is not memo.bias[v]
        assert other.bias[v] is not memo.bias[v]
        np.testing.assert_array_equal(plain.bias[v].params, memo.bias[v].params)
        np.testing.assert_array_equal(plain.bias[v].cov, memo.bias[v].cov)
    assert again.model.parallax is memo.model.parallax
    assert (plain.model.parallax.c0, plain.model.parallax.c1) == (memo.model.parallax.c0, memo.model.parallax.c1)
