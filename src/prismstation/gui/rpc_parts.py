"""The RPC model's own parts of the window (:mod:`prismstation.gui.sensors`; no Qt): the model
panel's Orientation section (what holds the fit, what the data do not determine) and the
strip's warning when an undetermined bias decides the heights; the orientation from a
reference DEM: its request and the stored record in words."""
from __future__ import annotations

import math

from prismstation.ops.fit import DEFAULT_REFERENCE_SIGMA_M, heights_not_fixed
from prismstation.ops.orientation import OrientRequest


def panel_sections(sol) -> tuple[list, list]:
    """The orientation's own section: what holds the fit (GCPs, the tie points held to the
    reference DEM with its σ) and, per view, its bias model and the parameters the data do not
    determine (the biases and the per-view residuals are every model's); a note when a bias
    the data cannot determine decides the heights (:func:`prismstation.ops.fit.heights_not_fixed`,
    the line ``prismstation dsm`` prints before its exit status 3)."""
    m, st = sol.model, sol.settings
    sigma = DEFAULT_REFERENCE_SIGMA_M if st.reference_sigma_m is None else st.reference_sigma_m
    rows = [["GCPs in the fit", str(m.gcps) if st.use_gcps else "not used (checked only)"],
            ["tie points held to the reference DEM", f"{m.held} (σ {sigma:g} m ⊕ slope)" if m.held else "none"]]
    for v, b in m.bias.items():
        weak = m.undetermined.get(v, ())
        rows.append([f"{v}", "held fixed (the datum)" if b.fixed else
                     f"{b.model}" + (f"; not determined: {', '.join(weak)}" if weak else "")])
    unfixed = heights_not_fixed(sol)
    return [("Orientation", ["", ""], rows)], ([(f"Heights not fixed: {unfixed}", "bad")] if unfixed else [])


def fit_warning(sol) -> tuple[tuple[str, ...], str]:
    """When a bias the data cannot determine decides the heights: the strip says so."""
    unfixed = heights_not_fixed(sol)
    if not unfixed:
        return (), ""
    return ("⚠ h rests on a bias the data do not determine", "⚠ h not fixed"), unfixed


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
