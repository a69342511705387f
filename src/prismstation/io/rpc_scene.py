"""Images with RPCs as a scene: the map projection the RPC model works through
(:class:`LonLatProjection`; :func:`to_map`, :func:`to_lonlat` for a grid's CRS), the RPC view of a scene file (:func:`rpc_view_from_dict`,
:func:`rpc_to_dict`) and the scene of a set of images (:func:`write_scene_for_images`, behind
``prismstation new --images``).

The scene's CRS is the WGS 84 UTM zone of the images' common footprint (each image's ground
footprint at its RPC's height offset, intersected: :func:`common_footprint`); images that see
no common ground are refused. The RPC's heights are ellipsoidal (WGS 84), like every height
the engine computes with.
"""
from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer

from prismstation.core.models.rpc import POLYNOMIALS, SCALARS, Rpc, wrap180
from prismstation.core.models.rpc_model import RpcModel, RpcView, ground_sample_distance
from prismstation.errors import InputError, ModelError, RasterReadError
from prismstation.io.inputs import open_raster_file
from prismstation.io.jsonfile import write_json
from prismstation.io.rpc import read_rpc

SCENE_FORMAT = "prismstation-scene/2"


class LonLatProjection:
    """Map metres of ``crs`` ↔ WGS 84 longitude, latitude (degrees), through pyproj; picklable
    (the transformers are made again where it is unpickled)."""

    def __init__(self, crs: str):
        self.crs = crs
        self._to = self._from = None

    def _make(self):
        wgs84 = CRS.from_epsg(4326)
        self._to = Transformer.from_crs(CRS.from_user_input(self.crs), wgs84, always_xy=True)
        self._from = Transformer.from_crs(wgs84, CRS.from_user_input(self.crs), always_xy=True)

    def to_lonlat(self, E, N):
        if self._to is None:
            self._make()
        lon, lat = self._to.transform(np.asarray(E, float), np.asarray(N, float), errcheck=False)
        return np.asarray(lon, float), np.asarray(lat, float)

    def from_lonlat(self, lon, lat):
        if self._from is None:
            self._make()
        E, N = self._from.transform(np.asarray(lon, float), np.asarray(lat, float), errcheck=False)
        return np.asarray(E, float), np.asarray(N, float)

    def __getstate__(self):
        return {"crs": self.crs}

    def __setstate__(self, state):
        self.__init__(state["crs"])


@lru_cache(maxsize=16)
def _transformer(crs: str, inverse: bool) -> Transformer:
    a, b = ("EPSG:4326", crs) if not inverse else (crs, "EPSG:4326")
    return Transformer.from_crs(a, b, always_xy=True)


def to_map(crs: str):
    """``(lon°, lat°) → (E, N)`` of ``crs``."""
    t = _transformer(str(crs), False)
    return lambda lon, lat: t.transform(lon, lat)


def to_lonlat(crs: str):
    """``(E, N)`` of ``crs`` → ``(lon°, lat°)``."""
    t = _transformer(str(crs), True)
    return lambda e, n: t.transform(e, n)


def utm_crs(lon: float, lat: float) -> str:
    """The WGS 84 / UTM zone of a point (``EPSG:326zz`` north, ``EPSG:327zz`` south)."""
    zone = min(int(math.floor((lon + 180.0) / 6.0)) + 1, 60)
    return f"EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"


def ground_footprint(rpc: Rpc, shape, name: str, per_edge: int = 8) -> np.ndarray:
    """``(k, 2)`` lon, lat (degrees) along the border of an image of ``shape`` ``(rows, cols)``
    at the RPC's height offset, clockwise from the top-left corner (points the RPC cannot
    invert are left out); fewer than three refused naming ``name``."""
    rows, cols = shape
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)
    x = np.concatenate([t * cols, np.full(per_edge, cols), (1 - t) * cols, np.zeros(per_edge)])
    y = np.concatenate([np.zeros(per_edge), t * rows, np.full(per_edge, rows), (1 - t) * rows])
    lon, lat, ok = rpc.localize_masked(x, y, np.full(x.shape, rpc.h_off))
    if ok.sum() < 3:
        raise InputError(f"the RPC cannot be inverted along the image's border at its height offset "
                         f"({rpc.h_off:g} m): no ground footprint", name)
    return np.column_stack([lon[ok], lat[ok]])


def _hull(p: np.ndarray) -> np.ndarray:
    """Convex hull ``(k, 2)``, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(map(tuple, p))

    def half(seq):
        out = []
        for q in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (q[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (q[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(q)
        return out[:-1]
    return np.array(half(pts) + half(pts[::-1]), float).reshape(-1, 2)


def _clip(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """The part of convex polygon ``subject`` inside convex ``clip`` (both counter-clockwise;
    Sutherland–Hodgman): ``(k, 2)``, empty when they do not meet."""
    out = subject
    for a, b in zip(clip, np.roll(clip, -1, axis=0)):
        if len(out) == 0:
            break
        side = (b[0] - a[0]) * (out[:, 1] - a[1]) - (b[1] - a[1]) * (out[:, 0] - a[0])
        nxt = []
        for i in range(len(out)):
            j = (i + 1) % len(out)
            if side[i] >= 0:
                nxt.append(out[i])
            if (side[i] >= 0) != (side[j] >= 0):
                nxt.append(out[i] + (out[j] - out[i]) * side[i] / (side[i] - side[j]))
        out = np.array(nxt, float).reshape(-1, 2)
    return out


def _area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) if len(p) >= 3 else 0.0


def common_footprint(footprints: dict) -> tuple[float, float]:
    """Longitude, latitude (degrees) of the centroid of the ground every image sees:
    ``footprints`` name → :func:`ground_footprint`. The footprints are intersected as convex
    polygons on a plane tangent at the first one (degrees of longitude scaled by the cosine of
    the latitude, across ±180° alike). Refused in one line naming the images when two of them
    do not overlap, or when all overlap pairwise but see nothing in common."""
    names = list(footprints)
    lon0 = float(np.mean(footprints[names[0]][:, 0]))
    lat0 = float(np.mean(np.concatenate([f[:, 1] for f in footprints.values()])))
    k = math.cos(math.radians(lat0))
    plane = {n: _hull(np.column_stack([wrap180(f[:, 0] - lon0) * k, f[:, 1]]))
             for n, f in footprints.items()}
    apart = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]
             if _area(_clip(plane[a], plane[b])) <= 0.0]
    if apart:
        pairs = "; ".join(f"{a} and {b}" for a, b in apart)
        raise InputError(f"the images do not overlap: {pairs} see no common ground (footprints at "
                         "their RPCs' height offsets): a project needs images of one place")
    common = plane[names[0]]
    for n in names[1:]:
        common = _clip(common, plane[n])
    area = _area(common)
    if area <= 0.0:
        raise InputError(f"the images see no ground in common, though each pair overlaps: "
                         f"{', '.join(names)}")
    x, y = common[:, 0], common[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    cx = float(np.sum((x + np.roll(x, -1)) * cross)) / (6 * area)
    cy = float(np.sum((y + np.roll(y, -1)) * cross)) / (6 * area)
    return float(wrap180(lon0 + cx / k)), cy


def rpc_to_dict(rpc: Rpc) -> dict:
    """The RPC as a scene file stores it: the ten offsets and scales and the four polynomials
    under :data:`prismstation.core.models.rpc.SCALARS` / ``POLYNOMIALS`` names (GDAL's conventions:
    0-based offsets, the first pixel's centre at 0)."""
    d = {k: float(getattr(rpc, k)) for k in SCALARS}
    d.update({k: [float(c) for c in getattr(rpc, k)] for k in POLYNOMIALS})
    return d


def rpc_from_dict(d, source: str, fail) -> Rpc:
    """:class:`Rpc` of a scene file's ``"rpc"`` object; ``fail(problem)`` reports a bad one."""
    if not isinstance(d, dict):
        fail('"rpc": expected an object with the RPC\'s offsets, scales and coefficients')
    missing = [k for k in (*SCALARS, *POLYNOMIALS) if k not in d]
    if missing:
        fail(f'"rpc": missing {", ".join(missing)}')
    try:
        return Rpc(*(float(d[k]) for k in SCALARS), *(np.asarray(d[k], float) for k in POLYNOMIALS),
                   source=source)
    except (TypeError, ValueError, ModelError) as exc:
        fail(f'"rpc": {exc}')


def rpc_view(name: str, rpc: Rpc, projection: LonLatProjection, image: str | None,
             pixel_size_m: float | None = None) -> RpcView:
    """An :class:`RpcView`: the image's shape read through rasterio when the file is there,
    the ground sample distance at its centre computed unless given."""
    shape = None
    if image is not None and Path(image).exists():
        try:
            with open_raster_file(image, f"view {name}") as ds:
                shape = (ds.height, ds.width)
        except RasterReadError as exc:
            raise InputError(str(exc).removeprefix(f"{image}: "), image) from None
    view = RpcView(name, rpc, projection, 1.0, image, shape)
    if pixel_size_m is None:
        try:
            pixel_size_m = ground_sample_distance(rpc, projection, *view.centre())
        except ModelError as exc:
            raise InputError(f"view {name}: the RPC cannot be inverted at the image centre ({exc})",
                             image) from None
    return RpcView(name, rpc, projection, float(pixel_size_m), image, shape)


def _shape(image: Path) -> tuple[int, int]:
    """``(rows, cols)`` of an image, opened through :func:`open_raster_file`."""
    try:
        with open_raster_file(image, "image") as ds:
            return ds.height, ds.width
    except RasterReadError as exc:
        raise InputError(str(exc).removeprefix(f"{image}: "), image) from None


def scene_dict_for_images(images, out_dir) -> dict:
    """The scene of ``images`` (two or more files with RPCs, read by
    :func:`prismstation.io.rpc.read_rpc`): views named by the files' stems, in the given order,
    image paths relative to ``out_dir``, the CRS the UTM zone of their common footprint
    (:func:`common_footprint`; images that do not overlap are refused)."""
    paths = [Path(p) for p in images]
    if len(paths) < 2:
        raise InputError(f"an RPC project needs two or more images, got {len(paths)}",
                         paths[0] if paths else None)
    names = {}
    for p in paths:
        if not p.is_file():
            raise InputError("image not found", p)
        if p.stem in names:
            raise InputError(f"two images are named {p.stem!r} (also {names[p.stem]}): a view is named "
                             "by its file's name, rename one", p)
        names[p.stem] = p
    rpcs = {name: read_rpc(p) for name, p in names.items()}
    crs = utm_crs(*common_footprint({p.name: ground_footprint(rpcs[n], _shape(p), str(p))
                                     for n, p in names.items()}))
    out_dir = Path(out_dir).resolve()
    views = {}
    for name, p in names.items():
        try:
            image = os.path.relpath(p.resolve(), out_dir)
        except ValueError:  # another drive on Windows
            image = str(p.resolve())
        views[name] = {"model": RpcModel.name, "image": image, "rpc_source": rpcs[name].source,
                       "rpc": rpc_to_dict(rpcs[name])}
    return {"format": SCENE_FORMAT, "crs": crs, "views": views}


def write_scene_for_images(images, scene_path) -> Path:
    """Write the scene of ``images`` (:func:`scene_dict_for_images`) to ``scene_path``."""
    scene_path = Path(scene_path)
    data = scene_dict_for_images(images, scene_path.parent)
    write_json(scene_path, data, indent=1)
    return scene_path
