"""The DSM export, once: ``prismstation dsm`` and Tools ▸ Export DSM… both call
:func:`export_dsm` with a :class:`DsmRequest`.

It computes the DSM of a fitted solution (:func:`prismstation.ops.dsm.make_dsm`), with the
project's geoid for orthometric heights and a reference DEM
(:class:`~prismstation.ops.reference_heights.DemHeights`) as the prior, and writes it
(:func:`prismstation.io.dsm.write_dsm`, atomic): a cancelled or failed export leaves no file
and does not touch an existing one; a read that failed is a ``RasterReadError`` naming the
image and the tile, a write that failed a ``WriteError`` naming the file.

Temporaries: the output is written as ``.NAME.XXXX.part.tif`` beside it and renamed at the end
(:mod:`prismstation.io.atomic`; the rename is atomic only within one file system); the uncompressed GeoTIFF the COG is copied from
(12 bytes a cell: ~0.6 GB for a 14,000 px scene at 5 m) goes to the system's temporary folder
(``TMPDIR``), see :func:`prismstation.io.dsm.write_dsm`.
"""
from __future__ import annotations

from dataclasses import dataclass

from prismstation.errors import ModelError
from prismstation.io.atomic import check_writable
from prismstation.io.dsm import write_dsm
from prismstation.io.project import project_geoid
from prismstation.ops import dsm as engine
from prismstation.ops.dsm import HEIGHT_MODELS, Dsm
from prismstation.ops.progress import checkpoint, scaled

__all__ = ["HEIGHT_MODELS", "DsmExport", "DsmRequest", "export_dsm"]

#: share of the progress range the computation takes (the rest: writing the file)
COMPUTE_SHARE = 0.97


@dataclass(frozen=True)
class DsmRequest:
    """What to export.

    ``output``: the GeoTIFF path. ``window``: (col0, row0, cols, rows) N-image pixels, None for
    the whole image. ``posting_m``: grid posting (m). ``orthometric``: heights through the
    project's geoid (else ellipsoidal). ``height_uncertainty_m``: a-priori ± of the prior
    (None: the engine's default). ``fill``: fill voids by interpolation (mask 2).
    ``min_fill_percent``: below it the export is a low fill (the file is written all the
    same). ``heights``: ``auto``, ``line`` or ``rays`` (:mod:`prismstation.core.surfaces.dsm_heights`).
    ``scheduler``, ``workers``: see :mod:`prismstation.ops.dsm_tiles`.
    """

    output: str
    window: tuple | None = None
    posting_m: float = 5.0
    orthometric: bool = False
    height_uncertainty_m: float | None = None
    fill: bool = False
    min_fill_percent: float = 90.0
    heights: str = "auto"
    scheduler: object = None
    workers: int | None = None


@dataclass(frozen=True)
class DsmExport:
    """A written DSM: its ``path``, the :class:`~prismstation.ops.dsm.Dsm` and the request."""

    path: str
    dsm: Dsm
    request: DsmRequest

    @property
    def seen_cells(self) -> int:
        """Cells all the images see."""
        return self.dsm.cells("seen")

    @property
    def fill_percent(self) -> float:
        """Matched share of the seen cells, percent."""
        return 100.0 * self.dsm.fill_fraction

    @property
    def filled_percent(self) -> float:
        """Share of the seen cells filled by interpolation, percent."""
        return 100.0 * self.dsm.cells("filled") / max(self.seen_cells, 1)

    @property
    def low_fill(self) -> bool:
        """Fewer seen cells matched than the request's minimum."""
        return self.fill_percent < self.request.min_fill_percent


def export_dsm(sol, project, request: DsmRequest, *, reference=None, progress=None) -> DsmExport:
    """Compute the DSM ``request`` asks for from the fitted solution ``sol`` of ``project`` and
    write it. ``reference``: a :class:`~prismstation.ops.reference_heights.DemHeights` (a
    reference DEM read onto the scene's grid, ellipsoidal) used as the prior, or None.
    ``progress(fraction, message)`` returning False cancels
    (:class:`~prismstation.errors.Cancelled`, no file left). A solution that did not fit
    (and is not oriented from a reference DEM) is a :class:`ModelError`."""
    if not sol.ok and project.settings.orientation != "dem":
        raise ModelError("; ".join(sol.messages) or "the model could not be fitted")
    check_writable(request.output)   # a folder that cannot be written: now, not after the work
    geoid = project_geoid(project) if request.orthometric else None
    prior = None if reference is None else (reference.grid.heights, tuple(reference.grid.transform)[:6])
    dsm = engine.make_dsm(sol, request.window, posting_m=request.posting_m, orthometric_geoid=geoid,
                          progress=scaled(progress, 0.0, COMPUTE_SHARE), reference=prior,
                          height_uncertainty_m=request.height_uncertainty_m, fill=request.fill,
                          scheduler=request.scheduler, workers=request.workers,
                          heights_model=request.heights)
    checkpoint(progress, COMPUTE_SHARE, "writing")
    # atomic: the whole file or none; a cancel once it is written still keeps the old file
    write_dsm(request.output, dsm, before_keep=lambda: checkpoint(progress, 1.0, "written"))
    return DsmExport(str(request.output), dsm, request)
