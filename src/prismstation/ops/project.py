"""Project creation: a scene, its ground points and image measurements → a saved project.

The ``prismstation new`` command and the demo call :func:`create`; so do the benchmarks and
the tests that need a project on disk.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from prismstation.errors import InputError
from prismstation.io.points import read_ground_points, read_measurements
from prismstation.io.atomic import write_together
from prismstation.io.jsonfile import dumps
from prismstation.io.lock import refuse_if_held
from prismstation.io.project import project_json
from prismstation.io.ranges import UNDULATION_M, outside_images
from prismstation.io.scene import read_scene, scene_from_dict
from prismstation.model.project import Project, default_geoid


def geoid_setting(value: str | None, scene) -> dict:
    """The project's geoid setting from the user's ``value``: None (:func:`default_geoid`: the
    scene's constant undulation, else ``auto``), ``"auto"``, a number of metres, or the path of a
    geoid grid file."""
    if value is None:
        return default_geoid(scene)
    if value == "auto":
        return {"kind": "auto", "value": scene.geoid_undulation_m or 0.0}
    try:
        metres = float(value)
    except ValueError:
        metres = None
    if metres is not None:
        if not UNDULATION_M[0] <= metres <= UNDULATION_M[1]:     # NaN is outside too
            raise InputError(f"--geoid {value}: a constant undulation must lie within {UNDULATION_M[0]:g} "
                             f"to {UNDULATION_M[1]:g} m (the Earth's geoid: -107 to +86 m)")
        return {"kind": "constant", "value": metres}
    if not Path(value).is_file():
        raise InputError("geoid grid not found", value)
    return {"kind": "grid", "path": str(Path(value).resolve())}


def create(project_path, scene_path, points=None, measurements=None, *, crs=None, height=None,
           geoid=None, force=False, scene_doc: dict | None = None) -> Project:
    """Build the project of ``scene_path`` (scene.json) with the ground points CSV ``points``
    (in ``crs``, default the scene's; ``height`` the kind of heights without a column) and the
    measurements CSV ``measurements``, save it at ``project_path`` and return it. An existing
    file is an :class:`~prismstation.errors.InputError` unless ``force``.

    ``scene_doc``: the scene as a dict, written at ``scene_path`` together with the project.
    Every input is read and checked before anything is written, and the files are written as
    one change (:func:`prismstation.io.atomic.write_together`): a command that fails leaves
    the previous files as they were and no new file behind."""
    project_path = Path(project_path)
    if project_path.exists() and not force:
        raise InputError("already exists (use --force to overwrite)", project_path)
    refuse_if_held(project_path)
    if scene_doc is None:
        scene = read_scene(scene_path)
    else:
        scene = scene_from_dict(scene_doc, Path(scene_path).parent, str(scene_path))
    project = Project(scene, str(Path(scene_path).resolve()), geoid=geoid_setting(geoid, scene))
    if project.settings.bias_model != scene.sensor.default_bias:
        project.set_settings(replace(project.settings, bias_model=scene.sensor.default_bias))
    pts = read_ground_points(points, crs=crs, to_crs=scene.crs, height=height) if points else []
    ms = read_measurements(measurements, views=list(scene.views)) if measurements else []
    project.load(pts, ms)
    bad = outside_images(scene, project.points, ms)
    if bad is not None:
        source = measurements if any(m.id == bad[0] for m in ms) and "view " in bad[1] else points
        raise InputError(f"point {bad[0]!r}: {bad[1]}", source)
    files = {} if scene_doc is None else {Path(scene_path): dumps(scene_doc, indent=1) + "\n"}
    files[project_path] = project_json(project, project_path)
    write_together(files, keep_backup=True)
    return project


def require_workflow(project, command: str, path=None) -> None:
    """Refuse ``command`` (``"orient-dem"``, ``"dsm"``) on a project whose sensor model does not
    offer it yet (:attr:`SensorModel.workflows <prismstation.core.models.sensor.SensorModel>`): one
    :class:`~prismstation.errors.InputError` naming the project, the model and the command."""
    sensor = project.scene.sensor
    if command not in sensor.workflows:
        raise InputError(f"{command} is not available yet for {sensor.description} (on this project: "
                         f"{', '.join(sorted(sensor.workflows))})", path)
