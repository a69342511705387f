"""An orientation from a reference DEM, of any sensor model: what it is asked with
(:class:`OrientRequest`), what it gives (:class:`Orientation`) and how a project takes it
(:func:`apply_orientation`).

Each sensor model orients in its own way — the PRISM triplet by patches of its relative DEM
and one adjustment of a shift field (:mod:`prismstation.ops.prism_project`), images with RPCs
by their relative DSM laid on the reference (:mod:`prismstation.ops.rpc_project`) — behind one
signature, ``orient(project, reference, request, *, solution=None, progress=None) →
Orientation`` (:mod:`prismstation.ops.sensors`), so that ``prismstation orient-dem`` and the
window's tool never ask which model it is.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from prismstation.core.orientation.conditioning import TARGET_M, OrientVerdict
from prismstation.errors import InputError
from prismstation.model.project import Project


@dataclass(frozen=True)
class OrientRequest:
    """What an orientation from a reference DEM is asked with; None: the model's default.

    ``sigma_apriori_m``: each view's a-priori geolocation σ per component (m); every search
    covers 3 σ (PRISM default 50 m; images with RPCs: a 100 m bound of the block's shift).
    ``posting_m``: the matching's grid posting (m; PRISM 30 m, RPC 8 pixels). ``patch_m``:
    the patch size (m; a PRISM triplet; None: :func:`default_patch_km` of the scene).
    ``target_m``: the planimetric and height σ an orientation must reach to be trusted (m; a
    PRISM triplet). ``with_gcps``: the project's
    GCPs adjusted together with the reference (a PRISM triplet; the RPC fit uses its GCPs
    anyway)."""

    sigma_apriori_m: float | None = None
    posting_m: float | None = None
    patch_m: float | None = None
    target_m: float = TARGET_M
    with_gcps: bool = False

    def __post_init__(self):
        named = (("a-priori geolocation σ", self.sigma_apriori_m), ("posting", self.posting_m),
                 ("patch size", self.patch_m), ("target σ", self.target_m))
        for what, v in named:
            if v is not None and not 0 < v < math.inf:
                raise InputError(f"the {what} must be a positive number of metres, got {v}")


@dataclass(frozen=True, eq=False)
class Orientation:
    """An orientation from a reference DEM, the same for every sensor model.

    ``verdict`` (:class:`~prismstation.core.orientation.conditioning.OrientVerdict`: ``ok``,
    ``too_smooth``, ``too_few``, ``failed``; its ``exit_status`` is the command's);
    ``record`` the project's ``dem_control`` once applied (JSON-ready, the model's own
    layout, read back by its ``control_from_record``), None when there is nothing to apply
    (the reference could not be used at all: refused); ``lines`` the result in words, what
    the command prints; ``document`` the result as JSON, beside the fit report
    (:meth:`json`); ``title`` a few words for an undo step; ``detail`` the model's own result
    (:class:`~prismstation.ops.orient_dem.DemOrientation`,
    :class:`~prismstation.ops.rpc_orient.RpcDemOrientation`) for its widgets;
    ``report_key``: where :meth:`json` puts the fit report (None: the document's items join
    the report's)."""

    verdict: OrientVerdict
    record: dict | None
    lines: tuple
    document: dict
    title: str
    detail: object = None
    report_key: str | None = None

    @property
    def ok(self) -> bool:
        return self.verdict.ok

    def noting(self, note: str) -> Orientation:
        """This orientation with ``note`` (what it could not check; "" leaves it as it is) in
        its verdict's message — the stored record's too — and its lines."""
        if not note:
            return self
        verdict = replace(self.verdict, message=f"{self.verdict.message}; {note}")
        record = self.record
        if record is not None and isinstance(record.get("verdict"), dict):
            record = {**record, "verdict": {**record["verdict"], "message": verdict.message}}
        return replace(self, verdict=verdict, record=record, lines=(*self.lines, note))

    @property
    def exit_status(self) -> int:
        return self.verdict.exit_status

    def json(self, report: dict | None) -> dict:
        """The JSON ``orient-dem --json`` writes: the document with the fit ``report`` (None:
        the document alone)."""
        if report is None:
            return dict(self.document)
        if self.report_key is None:
            return {**report, **self.document}
        return {**self.document, self.report_key: report}


def apply_orientation(project: Project, orientation: Orientation) -> None:
    """Make ``orientation`` the project's: its record the ``dem_control`` and the orientation
    "dem" (one change event). An orientation with nothing to apply is a ``ValueError``."""
    if orientation.record is None:
        raise ValueError("this orientation has nothing to apply: " + orientation.verdict.message)
    with project.batch():
        project.set_dem_control(orientation.record)
        project.set_settings(replace(project.settings, orientation="dem"))


def scene_km(scene) -> tuple[float, float]:
    """The reference image's extent on the ground, (across, along) kilometres."""
    n = scene.views[scene.reference_view]
    rows, cols = n.shape
    return cols * n.pixel_size_m / 1000.0, rows * n.pixel_size_m / 1000.0


def default_patch_km(scene) -> float:
    """A quarter of the scene's shorter side, between 1 and 4 km, in 0.05 km steps: 4 × 4
    patches on a small scene (the demo's 5 km: 1.25 km; a 10 km scene: 2.5 km), 4 km patches
    on a full PRISM scene. (4 km on a 10 km scene was 4 patches, refused as too few; on the
    5 km demo one patch: minutes of matching for a verdict of "too few".) 4 km where the
    image's size is not known."""
    if scene.views[scene.reference_view].shape is None:
        return 4.0
    side = min(scene_km(scene))
    return float(min(4.0, max(1.0, math.floor(side / 4.0 / 0.05) * 0.05)))
