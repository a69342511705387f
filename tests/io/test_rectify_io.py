"""Point pairs for a single-image rectification read from CSV (io.rectify_io)."""

import numpy as np
import pytest

from prismstation.errors import InputError
from prismstation.io.rectify_io import read_point_pairs
from tests.rectify_data import _csvs, _points


def test_read_point_pairs_one_view_and_kinds(tmp_path):
    src, dst = _points()
    pts, meas = _csvs(tmp_path, src, dst, icp=(2, 5))
    with pytest.raises(InputError, match="several views"):
        read_point_pairs(pts, meas)
    p = read_point_pairs(pts, meas, view="N")
    assert p.ids[0] == "G0" and len(p.ids) == 12 and "T1" not in p.ids
    assert np.allclose(p.xy, np.round(src, 4)) and list(np.nonzero(p.is_check)[0]) == [2, 5]

