"""``scene.json`` (docs/formats.md) → :class:`prismstation.core.models.scene.Scene`.

Here, and only here, a scene's sensor model is chosen: views of the PRISM model (format 1, or 2
without a ``"model"``) or images with RPCs (format 2, ``"model": "rpc"``,
:mod:`prismstation.io.rpc_scene`). A PRISM view's ``map_to_image`` comes from its
``map_to_image`` key when present, else from the inverse of the image's geotransform (rotated
ones included), read through rasterio.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pyproj import CRS
from pyproj.exceptions import CRSError

from prismstation.core.adjustment.affine import Affine2D
from prismstation.core.models import sensors
from prismstation.core.models.scene import GroundTrack, Scene, View
from prismstation.errors import InputError, RasterReadError
from prismstation.io import rpc_scene
from prismstation.io.inputs import open_raster_file
from prismstation.io.jsonfile import line_of, read_json
from prismstation.io.ranges import ALTITUDE_M, PIXEL_SIZE_M, UNDULATION_M

FORMAT = rpc_scene.SCENE_FORMAT  # "prismstation-scene/2"
#: the versions read: 1 (PRISM views only), 2 (a view may be an image with RPCs)
FORMATS = ("prismstation-scene/1", FORMAT)
#: the sensor models a view may name (``"model"``), the PRISM one when it names none
MODELS = tuple(sensors.MODELS)


def read_scene(path, images: dict | None = None) -> Scene:
    """Read and validate a scene file; every malformed field gets an :class:`InputError`.
    ``images``: view → image file used instead of the scene's (a project's relocated images)."""
    path = Path(path)
    data, text = read_json(path)
    return scene_from_dict(data, path.parent, str(path), text, images)


def scene_from_dict(data: dict, base_dir, source: str = "scene", text: str = "",
                    images: dict | None = None) -> Scene:
    """Build a Scene from the scene.json dict; image paths are relative to ``base_dir``;
    ``images``: view → image path (absolute) used instead of the scene's."""
    base_dir = Path(base_dir)
    if images:  # the views' image paths replaced before they are read
        views_in = data.get("views")
        if isinstance(views_in, dict):
            data = {**data, "views": {n: {**v, "image": str(images[n])} if n in images and isinstance(v, dict)
                                      else v for n, v in views_in.items()}}

    def fail(problem, key=None):
        raise InputError(problem, source, line_of(text, key) if key and text else None)

    fmt = data.get("format")
    if fmt not in FORMATS:
        if isinstance(fmt, str) and fmt.startswith("prismstation-scene/"):
            fail(f"scene format {fmt!r} is newer than this program reads ({FORMAT}); upgrade prismstation", "format")
        fail(f'"format" must be "{FORMAT}", found {fmt!r}', "format")
    crs = data.get("crs")
    try:
        crs_obj = CRS.from_user_input(crs)
    except (CRSError, TypeError):
        fail(f'"crs": {crs!r} is not a coordinate reference system pyproj knows', "crs")
    if crs_obj.is_geographic:
        fail(f'"crs": {crs} is geographic; a scene needs a projected CRS in metres (UTM)', "crs")
    units = {a.unit_name for a in crs_obj.axis_info[:2]}
    if units - {"metre", "meter"}:
        fail(f'"crs": {crs} is in {", ".join(sorted(units))}; a scene needs a projected CRS in metres (UTM)', "crs")
    model = _sensor_model(data, fmt, fail)
    if model == "rpc":
        return _rpc_scene(data, crs_obj.to_string(), base_dir, fail)
    hs = _number(data.get("satellite_altitude_m"), "satellite_altitude_m", fail, within=ALTITUDE_M)
    track = data.get("ground_track")
    try:
        tr = np.asarray(track, dtype=float)
        ok = tr.ndim == 2 and tr.shape[1] == 2 and len(tr) >= 2 and np.all(np.isfinite(tr))
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        fail('"ground_track": expected a list of two or more [E, N] points in flight order', "ground_track")
    if np.any(np.hypot(*np.diff(tr, axis=0).T) == 0):
        fail('"ground_track": two consecutive points coincide', "ground_track")
    views_in = data.get("views")
    if not isinstance(views_in, dict) or not views_in:
        fail('"views": expected an object of views, e.g. {"N": {...}, "F": {...}, "B": {...}}', "views")
    if any(v in views_in for v in "NFB") and not all(v in views_in for v in "NFB"):
        missing = [v for v in "NFB" if v not in views_in]
        fail(f'"views": a triplet needs N, F and B; missing {", ".join(missing)}', "views")
    views = {name: _view(name, v, base_dir, fail) for name, v in views_in.items()}
    geoid = data.get("geoid_undulation_m")
    if geoid is not None:
        geoid = _number(geoid, "geoid_undulation_m", fail, within=UNDULATION_M)
    known = {"format", "crs", "satellite_altitude_m", "ground_track", "views", "geoid_undulation_m"}
    extra = {k: v for k, v in data.items() if k not in known}
    return Scene(crs_obj.to_string(), hs, GroundTrack(tr), views, geoid, extra, sensors.model_named("prism"))


def _sensor_model(data: dict, fmt: str, fail) -> str:
    """The one sensor model the scene's views name (``"prism"`` when none does)."""
    views = data.get("views")
    if not isinstance(views, dict) or not views:
        fail('"views": expected an object of views, e.g. {"N": {...}, "F": {...}, "B": {...}}', "views")
    named = {n: v.get("model", "prism") if isinstance(v, dict) else "prism" for n, v in views.items()}
    for name, m in named.items():
        if m not in MODELS:
            fail(f'"views.{name}.model": {m!r} is not a sensor model this program knows ({", ".join(MODELS)})', "model")
        if m != "prism" and fmt != FORMAT:
            fail(f'"views.{name}.model": a view with RPCs needs "format": "{FORMAT}"', "format")
    if len(set(named.values())) > 1:
        fail(f'"views": every view of a scene follows one sensor model; found {", ".join(sorted(set(named.values())))}',
             "views")
    return next(iter(named.values()))


def _rpc_scene(data: dict, crs: str, base_dir: Path, fail) -> Scene:
    """The scene of images with RPCs (format 2): each view ``{"model": "rpc", "image", "rpc",
    ["pixel_size_m"]}``."""
    projection = rpc_scene.LonLatProjection(crs)
    views = {}
    for name, v in data["views"].items():
        key = f"views.{name}"
        if not isinstance(v, dict):
            fail(f'"{key}": expected an object with "image" and "rpc"', name)
        image = v.get("image")
        if image is not None and not (isinstance(image, str) and image):
            fail(f'"{key}.image": expected the path of the image file', "image")
        img_path = str(_image_path(base_dir, image, key, fail)) if image else None
        rpc = rpc_scene.rpc_from_dict(v.get("rpc"), str(v.get("rpc_source") or f"{key}.rpc"),
                                      lambda problem: fail(f'"{key}": {problem}', "rpc"))
        gsd = v.get("pixel_size_m")
        if gsd is not None:
            gsd = _number(gsd, f"{key}.pixel_size_m", fail, within=PIXEL_SIZE_M)
        views[name] = rpc_scene.rpc_view(name, rpc, projection, img_path, gsd)
    known = {"format", "crs", "views", "geoid_undulation_m"}
    geoid = data.get("geoid_undulation_m")
    if geoid is not None:
        geoid = _number(geoid, "geoid_undulation_m", fail, within=UNDULATION_M)
    extra = {k: v for k, v in data.items() if k not in known}
    return Scene(crs, None, None, views, geoid, extra, sensors.model_named("rpc"))


def _image_path(base_dir: Path, image: str, key: str, fail) -> Path:
    """The absolute path of a view's image; a path that is no local file path (a GDAL virtual
    file system, a URL, a NUL byte, a symbolic-link loop) fails."""
    low = image.strip().lower()
    if low.startswith(("/vsi", "\\vsi")) or "://" in low:
        fail(f'"{key}.image": {image[:60]!r} is not a local file; prismstation reads only local files', "image")
    try:
        return (base_dir / image).resolve()
    except (OSError, ValueError, RuntimeError) as exc:  # a NUL byte, a name too long, a link loop
        fail(f'"{key}.image": {image[:60]!r} is not a usable file path ({exc.__class__.__name__})', "image")


def _finite(value) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # a JSON integer beyond float range
        return False


def _number(value, key, fail, positive=False, within=None) -> float:
    """``value`` as a float; ``within``: the ``(lo, hi)`` it must fall in (:mod:`prismstation.io.ranges`)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value):
        fail(f'"{key}": expected a number, found {value!r}', key.split(".")[-1])
    if positive and value <= 0:
        fail(f'"{key}": must be positive, found {value}', key.split(".")[-1])
    if within is not None and not within[0] <= value <= within[1]:
        fail(f'"{key}": {value:g} is outside the plausible range {within[0]:g} to {within[1]:g}', key.split(".")[-1])
    return float(value)


def _view(name: str, v, base_dir: Path, fail) -> View:
    key = f"views.{name}"
    if not isinstance(v, dict):
        fail(f'"{key}": expected an object with "image" and "pixel_size_m"', name)
    p = _number(v.get("pixel_size_m"), f"{key}.pixel_size_m", fail, within=PIXEL_SIZE_M)
    ang = _number(v.get("along_track_angle_deg", 0.0), f"{key}.along_track_angle_deg", fail)
    if not -60 < ang < 60:
        fail(f'"{key}.along_track_angle_deg": {ang} is not a plausible viewing angle', "along_track_angle_deg")
    if name in ("F", "B") and ang <= 0:
        fail(f'"{key}.along_track_angle_deg": the {name} view needs a positive angle, found {ang}',
             "along_track_angle_deg")
    image = v.get("image")
    if not isinstance(image, str) or not image:
        fail(f'"{key}.image": expected the path of the image file', "image")
    img_path = _image_path(base_dir, image, key, fail)
    try:
        exists = img_path.exists()
    except OSError:  # a name too long: open_raster_file says so
        exists = True
    m2i = v.get("map_to_image")
    shape, gt_affine = None, None
    if exists:
        try:
            with open_raster_file(img_path, f"view {name}") as ds:
                shape = (ds.height, ds.width)
                t = ds.transform
                if not t.is_identity:
                    gt_affine = Affine2D([[t.a, t.b, t.c], [t.d, t.e, t.f]])
        except (InputError, RasterReadError) as exc:
            fail(f'"{key}.image": {exc}', "image")
    if m2i is not None:
        try:
            c = np.asarray(m2i, dtype=float)
            ok = c.shape == (6,) and np.all(np.isfinite(c))
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            fail(f'"{key}.map_to_image": expected six numbers [A1, A2, A3, A4, A5, A6]', "map_to_image")
        affine = Affine2D.from_coeffs(*c)
    elif gt_affine is not None:
        affine = gt_affine.inverse() if abs(np.linalg.det(gt_affine.linear)) > 0 else None
    else:
        affine = None
    if affine is None:
        why = "the image has no geotransform" if exists else f"the image {image} is not found"
        fail(f'"{key}": no "map_to_image" and {why}, so the view cannot be placed on the map', name)
    if abs(np.linalg.det(affine.linear)) < 1e-18:
        fail(f'"{key}.map_to_image": the affine is singular', "map_to_image")
    return View(name, affine, p, ang, str(img_path), shape)
