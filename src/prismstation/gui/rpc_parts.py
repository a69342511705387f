"""The RPC model's own parts of the window (:mod:`prismstation.gui.sensors`; no Qt): nothing
beyond what every model shows in the model panel, the strip and the plots; the orientation
from a reference DEM: its request and the stored record in words."""
from __future__ import annotations

import math

from prismstation.ops.orientation import OrientRequest


def panel_sections(sol) -> tuple[list, list]:
    """No section of its own: the biases and the per-view residuals are every model's."""
    return [], []


def fit_warning(sol) -> tuple[tuple[str, ...], str]:
    """Nothing beyond the fit's messages."""
    return (), ""


def plot_line(sol) -> None:
    """No height–parallax line: points are intersected."""
    return None


def orientable(scene) -> bool:
    """Any block of images with RPCs orients from a reference DEM."""
    return True


def orient_request(patch_m: float, posting_m: float, sigma_m: float, target_m: float) -> OrientRequest:
    """The orientation dialog's choices are the PRISM engine's (patches, the ancillary
    geolocation's σ): the RPC orientation keeps its own defaults (8-pixel posting, a 100 m
    bound of the block's shift)."""
    return OrientRequest()


def verdict_text(record: dict) -> str:
    """Nothing beyond :func:`orientation_text`: an orientation that is stored converged."""
    return ""


def applied_text(record: dict) -> str:
    """The status line once the orientation is applied: what it did."""
    return orientation_text(record)


def orientation_text(record: dict, state: str = "", scale: float | None = None) -> str:
    """One line on a stored orientation from a reference DEM: the block's shift with σ and each
    view's a-priori bias (``state`` and ``scale`` are the PRISM dock's)."""
    s, sg = record.get("shift_m") or [math.nan] * 3, record.get("sigma_m") or [math.nan] * 3
    biases = "; ".join(f"{v}: " + ", ".join(f"{p:+.2f} ± {q:.2f}" for p, q in zip(b["params"], b["sigma"]))
                       for v, b in (record.get("biases") or {}).items())
    return (f"Reference {str(record.get('reference', '?')).replace(chr(92), '/').rsplit('/', 1)[-1]}: the block "
            f"moved dE {s[0]:+.1f} ± {sg[0]:.1f}, dN {s[1]:+.1f} ± {sg[1]:.1f}, dh {s[2]:+.1f} ± {sg[2]:.1f} m. "
            f"A-priori biases (px) {biases}.")
