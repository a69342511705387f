"""io/formatting.py: numbers as text, the one way (reports, the text report, the window's
strip and tools, the command line)."""
import math

import numpy as np

from prismstation.io.formatting import DASH, fixed


def test_a_value_not_there_is_the_dash():
    assert [fixed(v) for v in (None, math.nan, math.inf, -np.inf, np.float32("nan"))] == [DASH] * 5


def test_decimals_and_sign():
    assert fixed(1.23456) == "1.23" and fixed(1.23456, 3) == "1.235"
    assert fixed(0.5, 1, sign=True) == "+0.5" and fixed(-0.5, 1, sign=True) == "-0.5"
    assert fixed(np.float64(2.0), 2) == "2.00" and fixed(np.float32(0.25), 2) == "0.25"


def test_counts_stay_counts():
    assert fixed(3) == "3" and fixed(True) == "True" and fixed(0, 3, sign=True) == "0"

