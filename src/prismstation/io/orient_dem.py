"""Deprecated: the orientation from a DEM is :mod:`prismstation.ops.orient_dem`. These names stay
only until :mod:`prismstation.io.dsm` imports them from their homes (io.windows, errors)."""
from prismstation.errors import Cancelled  # noqa: F401
from prismstation.io.windows import ImageWindows as _Images  # noqa: F401
from prismstation.io.windows import scaling as _scale  # noqa: F401
from prismstation.io.windows import shift as _shift  # noqa: F401
