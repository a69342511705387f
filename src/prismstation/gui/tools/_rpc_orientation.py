"""Tools ▸ Orient from reference DEM… on a project of images with RPCs.

The same job as ``prismstation orient-dem`` (the sensor model's orientation,
:mod:`prismstation.ops.workflows`: :func:`prismstation.ops.rpc_project.orient_rpc_project`) in
a worker with progress and Cancel, on the fitted solution the window shows: the images'
relative DSM laid on the reference gives each image's bias with its σ; applied as one undoable
step (the project's a-priori biases, orientation "dem"); a failed co-registration is not
applied, the status bar says why. The Orientation tool (:mod:`.dem_orientation`) calls
:func:`start` for every project that is not a PRISM triplet.
"""
from __future__ import annotations

import math

from prismstation.gui.tools._worker import run_with_progress


def orientable(project) -> bool:
    """Whether the project's sensor model orients from a reference DEM here: its workflows
    list ``orient-dem`` (a PRISM project only when it is a triplet)."""
    return project is not None and "orient-dem" in project.scene.sensor.workflows and (
        project.scene.is_triplet or project.scene.sensor.name != "prism")


def summary(record) -> str:
    """One line on an RPC orientation record: the block's shift with σ and each view's bias."""
    s, sg = record.get("shift_m") or [math.nan] * 3, record.get("sigma_m") or [math.nan] * 3
    biases = "; ".join(f"{v}: " + ", ".join(f"{p:+.2f} ± {q:.2f}" for p, q in zip(b["params"], b["sigma"]))
                       for v, b in (record.get("biases") or {}).items())
    return (f"Reference {str(record.get('reference', '?')).replace(chr(92), '/').rsplit('/', 1)[-1]}: the block "
            f"moved dE {s[0]:+.1f} ± {sg[0]:.1f}, dN {s[1]:+.1f} ± {sg[1]:.1f}, dh {s[2]:+.1f} ± {sg[2]:.1f} m. "
            f"A-priori biases (px) {biases}.")


def start(tool, reference_path):
    """Orient ``tool.ctx``'s project from ``reference_path`` in a worker; returns the Job (its
    result: ``(RpcDemOrientation, dsm)``), or None when there is no fitted solution."""
    from prismstation.gui.solver import snapshot
    from prismstation.gui.tools.dem_orientation import SetDemOrientation
    from prismstation.ops.rpc_project import orientation_record
    from prismstation.ops.workflows import workflows
    ctx = tool.ctx
    project, sol = ctx.project, ctx.solver.solution
    if project is None or (tool.job is not None and tool.job.isRunning()):
        return None
    if sol is None:
        ctx.status("Orientation from a reference DEM needs a fitted model", 8000)
        return None
    snap, path = snapshot(project), str(reference_path)

    def work(progress):
        return workflows(snap).orient(sol, snap, path, progress=progress)

    def done(result):
        orientation, _ = result
        tool.result = orientation
        if project is not ctx.project:
            return
        if not orientation:
            tool.message = ("Not applied: the images' DSM could not be laid on the reference: "
                            f"{orientation.coreg.reason}")
            ctx.status(tool.message, 30000)
            return
        record = orientation_record(project, orientation, path)
        ctx.undo_stack.push(SetDemOrientation(project, record, "dem", "Orient from DEM (RPC biases)"))
        tool.message = summary(record)
        ctx.status(tool.message, 30000)

    tool.job = run_with_progress(ctx, "Orientation from the reference DEM", work, done)
    return tool.job
