"""The σ of a reference DEM's heights the RPC fit holds tie points to: the stated σ ⊕ what the
DEM's cell cannot hold on a slope (slope × cell / √12), from the file's own cell size."""
import math

import numpy as np
from affine import Affine
from rasterio.crs import CRS

from prismstation.core.models.solution import Settings
from prismstation.io.dem import DemGrid
from prismstation.ops.fit import DEFAULT_REFERENCE_SIGMA_M, reference_sigma
from prismstation.ops.reference_heights import DemHeights


def _grid(slope, source_cell=(90.0, 90.0)):
    E = 500000.0 + 30.0 * (np.arange(40) + 0.5)
    h = np.tile(300.0 + slope * (E - E[0]), (40, 1))
    h[:, 30:] = 300.0                                    # a flat part east
    return DemHeights(DemGrid(h, CRS.from_epsg(32631), Affine(30.0, 0, 500000.0, 0, -30.0, 4000000.0),
                              "ellipsoidal", "ref.tif", source_cell))


def test_the_slope_term_and_the_settings_sigma():
    ref = _grid(0.5)
    en = np.array([[500300.0, 3999400.0], [501050.0, 3999400.0], [600000.0, 3999400.0]])  # slope, flat, outside
    s = reference_sigma(Settings(), ref)(en)
    assert abs(s[0] - math.hypot(DEFAULT_REFERENCE_SIGMA_M, 0.5 * 90 / math.sqrt(12))) < 1e-9
    assert s[1] == DEFAULT_REFERENCE_SIGMA_M and s[2] == DEFAULT_REFERENCE_SIGMA_M
    s6 = reference_sigma(Settings(reference_sigma_m=6.0), ref)(en)
    assert abs(s6[0] - math.hypot(6.0, 0.5 * 90 / math.sqrt(12))) < 1e-9 and s6[1] == 6.0
    # a file finer than the grid it is read on: the grid's cell is what it holds
    fine = reference_sigma(Settings(), _grid(0.5, (10.0, 10.0)))(en)
    assert abs(fine[0] - math.hypot(10.0, 0.5 * 30 / math.sqrt(12))) < 1e-9
    # a plain function of heights: the settings' number
    assert reference_sigma(Settings(reference_sigma_m=4.0), lambda en: en[:, 0] * 0) == 4.0
