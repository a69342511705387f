"""The rectification engine modules import neither rasterio, pyproj nor Qt (docs/architecture.md)."""
import subprocess
import sys


def test_core_modules_stay_below_io():
    code = ("import sys\n"
            "import prismstation.core.models.rectify, prismstation.core.models.resection\n"
            "import prismstation.core.surfaces.dsmstats, prismstation.core.matching.deblock\n"
            "bad = [m for m in ('rasterio', 'pyproj', 'PySide6', 'pyqtgraph') if m in sys.modules]\n"
            "print(','.join(bad))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
