"""``*.prismproj`` files (docs/formats.md): versioned JSON, saved atomically with a backup, and the
geoid object of a project's geoid setting (:func:`project_geoid`).

Top-level keys beside the points: ``dem_control`` (:attr:`Project.dem_control`),
``relocated_images`` (:attr:`Project.relocations`), ``product`` (:attr:`Project.product`),
``reference_dem`` (:attr:`Project.reference_dem`, relative to the project file; since format
version 2); keys this version does not know are kept in :attr:`Project.other` and written back.
``orientation`` (:attr:`Project.orientation`: the last fit's result as ``fit`` stored it —
each view's bias with its covariance, σ0, what the data determined; since format version 3,
with the settings' ``view_bias``, ``reference_sigma_m`` and ``use_gcps``).
Files of versions 1 (no reference DEM) and 2 (no stored orientation) are read as they are.
"""
from __future__ import annotations

import math
import os
from dataclasses import asdict
from pathlib import Path

from prismstation import __version__
from prismstation.core.models.prism import PARALLAX_MODELS
from prismstation.core.models.solution import Settings
from prismstation.errors import InputError
from prismstation.io import geoid as geoid_mod
from prismstation.io.atomic import write_atomic
from prismstation.io.lock import refuse_if_held
from prismstation.io.jsonfile import dumps, line_of, plain, read_json
from prismstation.io.ranges import SIGMA_M, UNDULATION_M, check_map, check_sigma, outside_images
from prismstation.io.scene import read_scene
from prismstation.model.points import HEIGHT_KINDS, KINDS, GroundPoint, Measurement
from prismstation.model.project import Project, has_ground

FORMAT_NAME = "prismstation-project"
VERSION = 3  # 2: "reference_dem"; 3: "orientation", the settings of a bias per view
SUFFIX = ".prismproj"
DEM_CONTROL, RELOCATED, PRODUCT, REFERENCE_DEM = "dem_control", "relocated_images", "product", "reference_dem"
ORIENTATION = "orientation"
_KNOWN = {"format", "saved_by", "scene", "settings", "geoid", "points", "measurements",
          DEM_CONTROL, RELOCATED, PRODUCT, REFERENCE_DEM, ORIENTATION, "recovery"}  # "recovery": the journal's own note


def _relative(path, base: Path) -> str:
    """``path`` relative to the folder ``base`` (absolute where there is no relative path:
    another drive)."""
    try:
        return os.path.relpath(Path(path).resolve(), base)
    except ValueError:
        return str(Path(path).resolve())


def project_to_dict(project: Project, path) -> dict:
    """The JSON document of ``project`` saved at ``path`` (scene and reference DEM paths made
    relative to it)."""
    base = Path(path).resolve().parent
    scene = project.scene_path
    if scene is not None:
        scene = _relative(scene, base)
    geoid = dict(project.geoid)
    if geoid.get("kind") == "grid" and geoid.get("path"):
        g = Path(geoid["path"])
        geoid["path"] = str(g) if not g.is_absolute() else g.as_posix()
    return {
        "format": f"{FORMAT_NAME}/{VERSION}",
        "saved_by": f"prismstation {__version__}",
        "scene": scene,
        "settings": settings_dict(project.settings),
        "geoid": geoid,
        "points": [
            {"id": p.id, "kind": p.kind, "E": plain(p.E), "N": plain(p.N), "H": plain(p.H),
             "height": p.height_kind, "sigma_xy_m": p.sigma_xy_m, "sigma_h_m": p.sigma_h_m,
             **({"extra": p.extra} if p.extra else {})}
            for p in project.points.values()],
        "measurements": [
            {"id": m.id, "view": m.view, "x": m.x, "y": m.y,
             **({"sigma_px": m.sigma_px} if m.sigma_px is not None else {})}
            for m in project.measurements.values()],
        **({DEM_CONTROL: project.dem_control} if project.dem_control is not None else {}),
        **({RELOCATED: dict(project.relocations)} if project.relocations else {}),
        **({PRODUCT: project.product} if project.product is not None else {}),
        **({REFERENCE_DEM: _relative(project.reference_dem, base)} if project.reference_dem else {}),
        **({ORIENTATION: plain(project.orientation)} if project.orientation is not None else {}),
        **{k: v for k, v in project.other.items() if k not in _KNOWN},
    }


def settings_dict(settings: Settings) -> dict:
    """The settings as the project file and the report write them: ``fixed_view``,
    ``view_bias`` (an object view → bias model), ``reference_sigma_m`` and ``use_gcps`` only
    when set (files of models that have none of them stay as they were)."""
    d = asdict(settings)
    d["view_bias"] = dict(settings.view_bias)
    for key, unset in (("fixed_view", None), ("view_bias", {}), ("reference_sigma_m", None), ("use_gcps", True)):
        if d.get(key) == unset:
            d.pop(key, None)
    return d


def project_json(project: Project, path) -> str:
    """The text of ``project`` saved at ``path``."""
    return dumps(project_to_dict(project, path), indent=1) + "\n"


def save_project(project: Project, path) -> None:
    """Save atomically (temporary file, fsync, rename), keeping the previous version as ``.bak``;
    a failure is a :class:`~prismstation.errors.WriteError` and leaves the file as it was. A
    project another process (a window) holds is refused (:func:`prismstation.io.lock.refuse_if_held`)."""
    refuse_if_held(path)
    write_atomic(path, project_json(project, path), keep_backup=True)


def load_project(path, *, scene_override=None) -> Project:
    """Read a project; refuses a newer format version without touching the file.

    ``scene_override``: path of the scene to use instead of the recorded one (relocated files).
    """
    path = Path(path)
    data, text = read_json(path)
    fmt = data.get("format")
    if not isinstance(fmt, str) or not fmt.startswith(FORMAT_NAME + "/"):
        raise InputError(f'not a prismstation project ("format" is {fmt!r})', path, line_of(text, "format"))
    try:
        version = int(fmt.split("/", 1)[1])
    except ValueError:
        raise InputError(f"unreadable format version in {fmt!r}", path, line_of(text, "format")) from None
    if version > VERSION:
        raise InputError(f"this project was written by a newer prismstation (format {fmt}); this "
                         f"program reads up to {FORMAT_NAME}/{VERSION}. The file was not changed.",
                         path, line_of(text, "format"))
    scene_rel = scene_override or data.get("scene")
    if not isinstance(scene_rel, str):
        raise InputError('"scene": expected the path of the scene.json', path, line_of(text, "scene"))
    try:
        scene_path = (path.parent / scene_rel).resolve() if scene_override is None else Path(scene_override).resolve()
        found = scene_path.is_file()
    except (OSError, ValueError, RuntimeError) as exc:  # a NUL byte, a name too long, a link loop
        raise InputError(f'"scene": {scene_rel[:60]!r} is not a usable file path ({exc.__class__.__name__})',
                         path, line_of(text, "scene")) from None
    if not found:
        raise InputError(f"scene file not found: {scene_path} (moved? open it with the scene relocated)",
                         path, line_of(text, "scene"))
    reloc = data.get(RELOCATED)
    if reloc is not None and not (isinstance(reloc, dict) and all(isinstance(v, str) for v in reloc.values())):
        raise InputError(f'"{RELOCATED}": expected an object view → path', path, line_of(text, RELOCATED))
    scene = read_scene(scene_path, images=relocated_images(reloc, path.parent))
    settings = _settings(data.get("settings", {}), path, text, scene)
    geoid = _geoid(data.get("geoid"), path, text)
    points, measurements = [], []
    for i, d in enumerate(_list(data, "points", path, text)):
        where = f'"points"[{i}]'
        try:
            kind = d.get("kind", "GCP")
            hk = d.get("height", "ellipsoidal")
            if kind not in KINDS or hk not in HEIGHT_KINDS or not isinstance(d["id"], str):
                raise ValueError("bad kind, height or id")
            vals = [math.nan if d.get(k) is None else float(d[k]) for k in ("E", "N", "H")]
            for k in ("sigma_xy_m", "sigma_h_m"):
                if d.get(k) is not None and not _number(d[k], minimum=0.0):
                    raise ValueError(f"{k} must be a number ≥ 0")
            if not isinstance(d.get("extra", {}), dict):
                raise ValueError("extra must be an object")
            p = GroundPoint(d["id"], *vals, height_kind=hk, kind=kind,
                            sigma_xy_m=d.get("sigma_xy_m"), sigma_h_m=d.get("sigma_h_m"),
                            extra=d.get("extra", {}))
            if kind != "TIE" and not has_ground(p):
                raise ValueError("a GCP or ICP needs E, N and H")
            why = check_map(p.E, p.N, p.H) or check_sigma("sigma_xy_m", p.sigma_xy_m, SIGMA_M, "m") \
                or check_sigma("sigma_h_m", p.sigma_h_m, SIGMA_M, "m")
            if why:
                raise ValueError(why)
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
            raise InputError(f"{where}: malformed point ({exc})", path, _line_of_id(text, d)) from None
        points.append(p)
    seen = {}
    for i, d in enumerate(_list(data, "measurements", path, text)):
        try:
            m = Measurement(str(d["id"]), str(d["view"]), float(d["x"]), float(d["y"]),
                            None if d.get("sigma_px") is None else float(d["sigma_px"]))
            if not (math.isfinite(m.x) and math.isfinite(m.y)):
                raise ValueError("non-finite coordinates")
            if m.sigma_px is not None and not _number(m.sigma_px, minimum=0.0, strict=True):
                raise ValueError("sigma_px must be a positive number")
            if (m.id, m.view) in seen:  # as the measurement CSV's reader refuses it
                raise ValueError(f"point {m.id!r} is measured twice in view {m.view} "
                                 f'(first: "measurements"[{seen[m.id, m.view]}])')
            seen[m.id, m.view] = i
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
            raise InputError(f'"measurements"[{i}]: malformed measurement ({exc})', path,
                             _line_of_id(text, d)) from None
        measurements.append(m)
    orientation = data.get(ORIENTATION) if version >= 3 else None
    if orientation is not None and not (isinstance(orientation, dict) and isinstance(orientation.get("views"), dict)):
        raise InputError(f'"{ORIENTATION}": expected an object with "views" (each view\'s fitted bias)', path,
                         line_of(text, ORIENTATION))
    control, product = data.get(DEM_CONTROL), data.get(PRODUCT)
    dem = data.get(REFERENCE_DEM) if version >= 2 else None
    if dem is not None and not (isinstance(dem, str) and dem and "\0" not in dem):
        raise InputError(f'"{REFERENCE_DEM}": expected the path of a DEM file', path, line_of(text, REFERENCE_DEM))
    if control is not None and not _dem_control_ok(control, scene):
        raise InputError(f'"{DEM_CONTROL}": expected an object with "patches" (a PRISM triplet: each with '
                         'numbers x, y, dE, dN, dh and their σ) or "biases" (images with RPCs: view → model, params)',
                         path, line_of(text, DEM_CONTROL))
    if product is not None and not isinstance(product, str):
        raise InputError(f'"{PRODUCT}": expected a folder path', path, line_of(text, PRODUCT))
    try:
        project = Project(scene, str(scene_path), settings=settings, geoid=geoid, points=points,
                          measurements=measurements, dem_control=control, relocations=reloc, product=product,
                          other={k: v for k, v in data.items() if k not in _KNOWN},
                          reference_dem=None if dem is None else str((path.parent / dem).resolve()),
                          orientation=orientation)
    except InputError as exc:
        raise InputError(exc.problem, path) from None
    bad = outside_images(project.scene, project.points, project.measurements.values())
    if bad is not None:
        raise InputError(f"point {bad[0]!r}: {bad[1]}", path, _line_of_id(text, {"id": bad[0]}))
    return project


def relocated_images(relocations: dict | None, base=None) -> dict:
    """View → image file of the ``relocated_images`` that are there (a relative path: from
    ``base``, the project's folder); a view whose recorded file is not there keeps the scene's."""
    out = {}
    for name, path in (relocations or {}).items():
        p = Path(path)
        if not p.is_absolute() and base is not None:
            p = Path(base) / p
        try:
            if p.is_file():
                out[name] = str(p.resolve())
        except (OSError, ValueError):  # a NUL byte, a name too long: not there
            pass
    return out


def apply_relocations(project: Project, base=None) -> None:
    """The project's scene read again with the image files recorded in
    ``project.relocations`` (:func:`relocated_images`). :func:`load_project` reads the scene
    so, for the window and the command line alike; the window calls this after the operator
    relocated images."""
    images = relocated_images(project.relocations, base)
    if images and project.scene_path:
        project.scene = read_scene(project.scene_path, images=images)


def _dem_control_ok(control, scene) -> bool:
    """The ``dem_control`` record has the shape its readers (the fit, the window's vectors)
    take for granted, by the scene's sensor model (:data:`_CONTROL_SHAPES`; a model not listed
    there: any object, its ``control_from_record`` checks it at the fit)."""
    return isinstance(control, dict) and _CONTROL_SHAPES.get(scene.sensor.name, lambda c: True)(control)


def _patches_ok(control) -> bool:
    """A PRISM triplet's record: ``patches``, each with the numbers (or nulls) :data:`_PATCH_NUMBERS`."""
    patches = control.get("patches")
    return isinstance(patches, list) and all(
        isinstance(q, dict) and all(k in q and (q[k] is None or _number(q[k])) for k in _PATCH_NUMBERS)
        for q in patches)


def _biases_ok(control) -> bool:
    """An RPC block's record: ``biases``, view → ``{"model": name, "params": [...], ...}``."""
    biases = control.get("biases")
    return isinstance(biases, dict) and all(
        isinstance(b, dict) and isinstance(b.get("model"), str) and isinstance(b.get("params"), list)
        for b in biases.values())


#: sensor model name → the check of its ``dem_control`` record's shape
_CONTROL_SHAPES = {"prism": _patches_ok, "rpc": _biases_ok}


#: the numbers (or nulls) every saved patch holds
_PATCH_NUMBERS = ("x", "y", "dE", "dN", "dh", "sigma_E", "sigma_N", "sigma_h")


def _number(v, minimum=None, strict=False) -> bool:
    """``v`` is a finite number (not a bool), above ``minimum`` when given."""
    if isinstance(v, int) and abs(v) > 2**1023:  # a JSON integer beyond float range
        return False
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return False
    return minimum is None or (v > minimum if strict else v >= minimum)


def _settings(raw, path, text, scene) -> Settings:
    """The model settings of a project, each checked against what the scene's sensor model
    offers (a wrong type would fail in the fit)."""
    line = line_of(text, "settings")
    if not isinstance(raw, dict):
        raise InputError('"settings": expected an object', path, line)
    raw = dict(raw)
    vb = raw.get("view_bias", {})
    if not (isinstance(vb, dict) and all(isinstance(v, str) for v in vb.values())):
        raise InputError('"settings.view_bias": expected an object view → bias model', path,
                         line_of(text, "view_bias") or line)
    raw["view_bias"] = tuple(sorted(vb.items()))
    try:
        s = Settings(**raw)
    except TypeError as exc:
        raise InputError(f'"settings": {exc}', path, line) from None
    sensor = scene.sensor
    parallax = sensor.parallax_models or PARALLAX_MODELS  # kept as written where the model has none
    checks = {"bias_model": (isinstance(s.bias_model, str) and s.bias_model in sensor.bias_models,
                             f"one of {', '.join(sensor.bias_models)}"),
              "parallax_model": (isinstance(s.parallax_model, str) and s.parallax_model in parallax,
                                 f"one of {', '.join(parallax)}"),
              "fixed_view": (s.fixed_view is None or (sensor.holds_view_fixed and s.fixed_view in scene.views),
                             f"null or one of {', '.join(scene.views)}" if sensor.holds_view_fixed else "null"),
              "sigma_px": (_number(s.sigma_px, 0.0, strict=True), "a positive number"),
              "blunder_threshold": (_number(s.blunder_threshold, 0.0, strict=True), "a positive number"),
              "mean_height": (s.mean_height is None or _number(s.mean_height), "a number or null"),
              "orientation": (getattr(s, "orientation", "gcp") in ("gcp", "dem"), '"gcp" or "dem"'),
              "view_bias": ((not s.view_bias or sensor.holds_view_fixed)
                            and all(v in scene.views and m in sensor.bias_models for v, m in s.view_bias),
                            f"views of the scene ({', '.join(scene.views)}) → one of {', '.join(sensor.bias_models)}"
                            if sensor.holds_view_fixed else "nothing (one bias model for every view)"),
              "reference_sigma_m": (s.reference_sigma_m is None or _number(s.reference_sigma_m, 0.0, strict=True),
                                    "a positive number of metres or null"),
              "use_gcps": (isinstance(s.use_gcps, bool) and (s.use_gcps or sensor.holds_view_fixed),
                           "true or false" if sensor.holds_view_fixed else "true (the model is fitted to its GCPs)")}
    for key, (ok, want) in checks.items():
        if not ok:
            raise InputError(f'"settings.{key}": expected {want}, found {getattr(s, key)!r}', path,
                             line_of(text, key) or line)
    return s


def _geoid(g, path, text):
    """The geoid setting: null, or {"kind": "constant"|"auto", "value": m} or {"kind": "grid", "path": ...}."""
    if g is None:
        return None
    ok = isinstance(g, dict) and g.get("kind") in ("constant", "auto", "grid")
    if ok and g["kind"] == "grid":
        ok = isinstance(g.get("path"), str) and bool(g["path"])
    elif ok:   # a constant needs its value; an automatic one falls back on it (0 m if none)
        v = g.get("value")
        ok = (v is None and g["kind"] == "auto") or (_number(v) and UNDULATION_M[0] <= v <= UNDULATION_M[1])
    if not ok:
        raise InputError(f'"geoid": expected {{"kind": "constant", "value": metres}} (within '
                         f'{UNDULATION_M[0]:g} to {UNDULATION_M[1]:g} m), {{"kind": "auto"}} '
                         f'or {{"kind": "grid", "path": file}}, found {g!r}', path, line_of(text, "geoid"))
    return g


def _list(data, key, path, text) -> list:
    v = data.get(key, [])
    if not isinstance(v, list):
        raise InputError(f'"{key}": expected a list', path, line_of(text, key))
    return v


def _line_of_id(text, d):
    if isinstance(d, dict) and isinstance(d.get("id"), str):
        i = text.find(dumps(d["id"]))
        return text.count("\n", 0, i) + 1 if i >= 0 else None
    return None


def project_geoid(project: Project):
    """The geoid object of the project's setting (grids read once and cached)."""
    s = project.geoid or {}
    base = Path(project.scene_path).parent if project.scene_path else None
    if s.get("kind") == "grid":
        p = Path(s.get("path", ""))
        if not p.is_absolute() and base is not None:
            p = base / p
        try:
            found = p.is_file()
        except OSError:  # a name too long...
            found = False
        if not found:
            raise InputError(f"geoid grid not found: {p}")
        return geoid_mod.grid_geoid(str(p))
    return geoid_mod.geoid_from_setting(s, base)
