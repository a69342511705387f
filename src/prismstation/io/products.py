"""A JAXA PRISM 1B2 product folder -> the ``scene.json`` dict of docs/formats.md.

:func:`scene_dict_from_product` accepts a folder holding one view, a folder holding the three
views (N, F, B) side by side, or a folder of three view folders; CEOS (``LED-``/``IMG-`` files,
see :mod:`prismstation.io.ceos`) or GeoTIFF (``IMG-*.tif``, :mod:`prismstation.io.jaxa_geotiff`).

What comes from where:

- ``crs``: the leader's UTM zone and hemisphere (CEOS) or the GeoTIFF CRS.
- ``map_to_image``: the leader's F4 affine (CEOS) or the inverse geotransform (GeoTIFF).
- ``ground_track``: sub-satellite points of the leader's state vectors, 30 s either side of the
  nadir scene-centre time, every 5 s (CEOS with times); otherwise a line through the nadir
  scene centre along the image's line direction (lines are acquired in flight order).
- ``satellite_altitude_m``: mean geodetic height of the satellite over that track; else the
  leader's nominal altitude; else 691 650 m.
- ``along_track_angle_deg`` of F and B: the angle at the view's scene centre between the
  ellipsoid normal and the satellite at the view's scene-centre time (state vectors); without
  them, the PRISM telescope tilt of 23.8 deg carried to the ground on a spherical Earth
  (``sin(theta) = (R + H) / R * sin(23.8 deg)``, 26.6 deg for 691.65 km).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from prismstation.core.models.scene import reference_view
from prismstation.errors import InputError
from prismstation.io import ceos
from prismstation.io.atomic import write_atomic
from prismstation.io.jaxa_geotiff import find_summary, read_geotiff_view
from prismstation.io.jsonfile import dumps

SCENE_FORMAT = "prismstation-scene/1"


def _invert(m2i, x: float, y: float):
    a1, a2, a3, a4, a5, a6 = m2i
    det = a1 * a4 - a2 * a3
    return ((a4 * (x - a5) - a2 * (y - a6)) / det, (-a3 * (x - a5) + a1 * (y - a6)) / det)


def _find(folder: Path, pattern: str) -> list[Path]:
    found = sorted(folder.glob(pattern)) + sorted(folder.glob(f"*/{pattern}"))
    return [p for p in found if p.is_file()]


def _ceos_summary(led: Path) -> Path | None:
    leds = list(led.parent.glob("LED-*"))
    if len(leds) == 1:
        for name in ("summary.txt", "SUMMARY.TXT"):
            if (led.parent / name).is_file():
                return led.parent / name
    scene = led.name[4:].split("-")[0]
    for cand in sorted(led.parent.glob("*ummary*.txt")):
        if scene in cand.name:
            return cand
    return None


def _tif_dir(img: Path, image_dir) -> Path:
    if image_dir is not None:
        return Path(image_dir)
    return img.parent if os.access(img.parent, os.W_OK) else Path.cwd()


def _centre_check(v) -> float | None:
    """Pixels between the leader's scene-centre position mapped through the F4 affine and the
    image centre: a few pixels confirm the reading of the F4 relation on a real product."""
    if v.centre_en is None:
        return None
    m = v.map_to_image
    x = m[0] * v.centre_en[0] + m[1] * v.centre_en[1] + m[4]
    y = m[2] * v.centre_en[0] + m[3] * v.centre_en[1] + m[5]
    return round(float(np.hypot(x - v.width / 2.0, y - v.height / 2.0)), 3)


def _ceos_views(leds: list[Path], image_dir) -> dict:
    views = {}
    for led in leds:
        summary = _ceos_summary(led)
        v = ceos.read_ceos_view(led, summary)
        if v.view in views:
            raise InputError(f"two {v.view} views in the product ({views[v.view]['leader'].name} "
                             f"and {led.name})", led)
        tif = _tif_dir(v.image_file, image_dir) / (v.image_file.name + ".tif")
        fresh = tif.exists() and tif.stat().st_mtime >= v.image_file.stat().st_mtime
        if not fresh:
            ceos.write_geotiff(v.image_file, tif, v.crs, v.map_to_image)
        views[v.view] = {
            "view": v.view, "image": tif, "crs": v.crs, "map_to_image": list(v.map_to_image),
            "pixel_size_m": v.pixel_size_m, "width": v.width, "height": v.height,
            "time": ceos.summary_time(v.summary, "Img_SceneCenterDateTime", summary or led),
            "scene_id": v.scene_id, "product_id": v.product_id, "summary": v.summary,
            "leader": led, "summary_file": summary, "state_vectors": v.state_vectors, "altitude_m": v.altitude_m,
            "extra": {"source": str(v.image_file), "ceos_f4": list(v.f4),
                      "line_spacing_m": v.line_spacing_m, "nominal_heading": v.heading,
                      "centre_check_px": _centre_check(v)},
        }
    return views


def _fallback_track(view: dict) -> list:
    """A line through the view's centre along its image line direction (+y), 60 km long."""
    cx, cy = view["width"] / 2.0, view["height"] / 2.0
    e0, n0 = _invert(view["map_to_image"], cx, cy)
    e1, n1 = _invert(view["map_to_image"], cx, cy + 1.0)
    d = np.array([e1 - e0, n1 - n0])
    d /= np.linalg.norm(d)
    return [[e0 - 30000 * d[0], n0 - 30000 * d[1]], [e0, n0], [e0 + 30000 * d[0], n0 + 30000 * d[1]]]


def scene_dict_from_views(views: dict, product: Path, kind: str) -> dict:
    """The docs/formats.md scene dict from view records (see module docstring for the sources)."""
    if len(views) == 2:
        raise InputError(f"a triplet needs N, F and B; the product has only {', '.join(views)}",
                         product)
    crss = {v["crs"] for v in views.values()}
    if len(crss) != 1:
        each = ", ".join(f"{k} {v['crs']}" + (f" ({v['leader'].name})" if v.get("leader") else "")
                         for k, v in views.items())
        raise InputError(f"the views are in different coordinate systems: {each}", product)
    crs = crss.pop()
    ref = views[reference_view(views)]
    sv = next((v.get("state_vectors") for v in views.values() if v.get("state_vectors")), None)
    track, alt, alt_src = None, None, None
    if sv is not None and ref["time"] is not None:
        track, alt = ceos.sub_satellite_track(sv, crs, ref["time"])
        alt_src = "state vectors"
        if len(track) < 2:
            raise InputError("the state vectors do not cover the scene-centre time "
                             f"{ref['time'].isoformat()}", ref.get("leader", product))
    if not track or len(track) < 2:
        track = _fallback_track(ref)
    if alt is None:
        alt = next((v.get("altitude_m") for v in views.values() if v.get("altitude_m")), None)
        alt_src = "leader (nominal)" if alt else "ALOS nominal"
        alt = alt or ceos.NOMINAL_ALTITUDE_M
    out_views, times = {}, {}
    single = len(views) == 1
    for letter, v in views.items():
        angle, src = 0.0, "nadir"
        cx, cy = _invert(v["map_to_image"], v["width"] / 2.0, v["height"] / 2.0)
        if letter in "FB":
            if sv is not None and v["time"] is not None:
                angle = ceos.incidence_deg(sv.at(v["time"]), crs, cx, cy)
                src = "state vectors at the scene-centre time"
                if not 0 < angle < 60:  # read_scene's plausible range
                    when = v["time"].isoformat() + (f" ({v['summary_file'].name})" if v.get("summary_file") else "")
                    raise InputError(f"view {letter}: the state vectors give a viewing angle of {angle:.1f} "
                                     f"deg at the scene centre at {when}", v.get("leader", product))
            else:
                angle = ceos.ground_angle_deg(ceos.PRISM_TILT_DEG, alt)
                src = f"PRISM tilt {ceos.PRISM_TILT_DEG} deg at the sensor, spherical Earth"
        name = v["product_id"].rsplit("_", 1)[-1] if single else letter
        out_views[name] = {
            "image": str(Path(v["image"]).resolve()), "pixel_size_m": float(v["pixel_size_m"]),
            "along_track_angle_deg": round(float(angle), 4), "along_track_angle_source": src,
            "map_to_image": [float(a) for a in v["map_to_image"]],
            "scene_id": v["scene_id"], "product_id": v["product_id"],
            "scene_centre_en": [float(cx), float(cy)], **v.get("extra", {}),
        }
        if v["time"] is not None:
            times[name] = v["time"].isoformat()
    return {
        "format": SCENE_FORMAT, "crs": crs, "satellite_altitude_m": round(float(alt), 3),
        "satellite_altitude_source": alt_src,
        "ground_track": [[round(e, 3), round(n, 3)] for e, n in track],
        "views": out_views, "scene_id": ref["scene_id"], "times": times,
        "product": {"kind": kind, "path": str(Path(product).resolve())},
    }


def scene_dict_from_product(path, image_dir=None) -> dict:
    """The ``scene.json`` dict (docs/formats.md) of a JAXA PRISM 1B2 product.

    Parameters
    ----------
    path : path-like
        A product folder (one view, three views side by side, or three view folders) or one of
        its files.
    image_dir : path-like, optional
        Where GeoTIFF copies of CEOS images go; default beside the ``IMG-`` file when that folder
        is writable, else the current directory. Existing up-to-date copies are reused.

    Image paths in the dict are absolute. Raises :class:`InputError` naming the file and problem.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file or folder", path)
    folder = path if path.is_dir() else path.parent
    leds = _find(folder, "LED-*")
    if leds:
        return scene_dict_from_views(_ceos_views(leds, image_dir), folder, "JAXA CEOS 1B2")
    tifs = [p for p in _find(folder, "IMG-*") if p.suffix.lower() in (".tif", ".tiff")]
    if tifs:
        views = {}
        for tif in tifs:
            v = read_geotiff_view(tif, find_summary(tif))
            key = v["view"] or f"view{len(views) + 1}"
            if key in views:
                raise InputError(f"two {key} views in the product", tif)
            views[key] = v
        if len(views) > 1 and any(k not in "NFB" for k in views):
            raise InputError("cannot tell N, F and B apart from the product ids "
                             f"{[v['product_id'] for v in views.values()]}", folder)
        return scene_dict_from_views(views, folder, "JAXA GeoTIFF 1B2")
    imgs = _find(folder, "IMG-*")
    if imgs:
        raise InputError(f"{imgs[0].name} has no leader file (LED-*) beside it", imgs[0])
    raise InputError("not a JAXA PRISM product: no LED-* (CEOS) or IMG-*.tif (GeoTIFF) files "
                     "here or one folder down", folder)


def scene_dict_for_folder(product, out_dir) -> dict:
    """:func:`scene_dict_from_product` with the image paths relative to ``out_dir`` where
    possible (the scene.json is to be written there)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    scene = scene_dict_from_product(product)
    for v in scene["views"].values():
        try:
            v["image"] = os.path.relpath(v["image"], out_dir.resolve())
        except ValueError:  # another drive on Windows
            pass
    return scene


def write_scene_for_product(product, out_dir) -> Path:
    """Write ``scene.json`` for ``product`` into ``out_dir`` and return its path (image paths
    relative to it where possible)."""
    target = Path(out_dir) / "scene.json"
    write_atomic(target, dumps(scene_dict_for_folder(product, out_dir), indent=2) + "\n", keep_backup=False)
    return target
