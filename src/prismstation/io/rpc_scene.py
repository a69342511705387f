"""Images with RPCs as a scene: the map projection the RPC model works through
(:class:`LonLatProjection`), the RPC view of a scene file (:func:`rpc_view_from_dict`,
:func:`rpc_to_dict`) and the scene of a set of images (:func:`write_scene_for_images`, behind
``prismstation new --images``).

The scene's CRS is the WGS 84 UTM zone of the images' centre; the RPC's heights are
ellipsoidal (WGS 84), like every height the engine computes with.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer

from prismstation.core.rpc import POLYNOMIALS, SCALARS, Rpc
from prismstation.core.rpc_model import RpcModel, RpcView, ground_sample_distance
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


def utm_crs(lon: float, lat: float) -> str:
    """The WGS 84 / UTM zone of a point (``EPSG:326zz`` north, ``EPSG:327zz`` south)."""
    zone = min(int(math.floor((lon + 180.0) / 6.0)) + 1, 60)
    return f"EPSG:{32600 + zone if lat >= 0 else 32700 + zone}"


def rpc_to_dict(rpc: Rpc) -> dict:
    """The RPC as a scene file stores it: the ten offsets and scales and the four polynomials
    under :data:`prismstation.core.rpc.SCALARS` / ``POLYNOMIALS`` names (GDAL's conventions:
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


def scene_dict_for_images(images, out_dir) -> dict:
    """The scene of ``images`` (two or more files with RPCs, read by
    :func:`prismstation.io.rpc.read_rpc`): views named by the files' stems, in the given order,
    image paths relative to ``out_dir``."""
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
    crs = utm_crs(float(np.mean([r.lon_off for r in rpcs.values()])),
                  float(np.mean([r.lat_off for r in rpcs.values()])))
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
