"""JAXA ALOS PRISM level 1B2 products in GeoTIFF form: ``IMG-*.tif`` with ``summary.txt`` (and
``HDR-*.txt``, ``RPC-*.txt``) beside it, the layout GDAL's ALOS metadata reader looks for.

A view is placed by the GeoTIFF geotransform: ``map_to_image`` is its inverse (rotated
geotransforms included). The product carries no state vectors, so the ground track is taken
through the nadir scene centre along the image's line direction (see
:func:`prismstation.io.products.scene_dict_from_views`).
"""
from __future__ import annotations

import re
from pathlib import Path

from prismstation.errors import InputError, RasterReadError
from prismstation.io.inputs import open_raster_file
from prismstation.io.ceos import read_summary, summary_time, view_letter


def find_summary(tif_path) -> Path | None:
    """``summary.txt`` beside ``tif_path`` (any case), or a ``*summary*.txt`` naming its scene."""
    tif_path = Path(tif_path)
    for name in ("summary.txt", "SUMMARY.TXT"):
        if (tif_path.parent / name).is_file():
            return tif_path.parent / name
    scene = re.sub(r"^IMG-(\d\d-)?", "", tif_path.stem).split("-")[0]
    for cand in sorted(tif_path.parent.glob("*ummary*.txt")):
        if scene and scene in cand.name:
            return cand
    return None


def side_file(tif_path, prefix: str) -> Path | None:
    """``HDR``/``RPC`` text file of an ``IMG-`` GeoTIFF, named as GDAL's ALOS reader expects:
    the prefix replaces the first 6 (``IMG-01-``) or 3 characters of the name, ``.txt``."""
    tif_path = Path(tif_path)
    for cut in (6, 3):
        for ext in (".txt", ".TXT"):
            cand = tif_path.with_name(prefix + tif_path.stem[cut:] + ext)
            if len(tif_path.stem) >= cut and cand.is_file():
                return cand
    return None


def read_geotiff_view(tif_path, summary_path=None) -> dict:
    """One view of a JAXA GeoTIFF 1B2 product.

    Returns
    -------
    dict
        ``view`` (N/F/B or None), ``image`` (path), ``crs``, ``map_to_image`` [A1..A6] (inverse
        geotransform, metres -> docs/model.md pixels), ``pixel_size_m``, ``width``, ``height``,
        ``time`` (scene centre, aware datetime or None), ``scene_id``, ``product_id``,
        ``summary`` (dict), ``extra`` (paths of the ``RPC``/``HDR`` files found beside it).
    """
    tif_path = Path(tif_path)
    try:
        with open_raster_file(tif_path, "image") as ds:
            transform, crs, width, height = ds.transform, ds.crs, ds.width, ds.height
    except RasterReadError as exc:
        raise InputError(str(exc).removeprefix(f"{tif_path}: "), tif_path) from None
    if crs is None or not crs.is_projected:
        raise InputError("the GeoTIFF has no projected CRS (expected UTM)", tif_path)
    if transform.is_identity or abs(transform.determinant) < 1e-12:
        raise InputError("the GeoTIFF has no usable geotransform", tif_path)
    inv = ~transform
    summary_path = summary_path or find_summary(tif_path)
    summary = read_summary(summary_path) if summary_path else {}
    product_id = summary.get("Pds_ProductID", tif_path.stem.split("-")[-1])
    epsg = crs.to_epsg()
    return {
        "view": view_letter(product_id) or view_letter(tif_path.stem),
        "image": tif_path, "crs": f"EPSG:{epsg}" if epsg else crs.to_wkt(),
        "map_to_image": [inv.a, inv.b, inv.d, inv.e, inv.c, inv.f],
        "pixel_size_m": float((transform.a ** 2 + transform.d ** 2) ** 0.5),
        "width": width, "height": height,
        "time": summary_time(summary, "Img_SceneCenterDateTime", summary_path),
        "scene_id": summary.get("Scs_SceneID", tif_path.stem[4:].split("-")[0]),
        "product_id": product_id, "summary": summary,
        "extra": {k: str(f) for k, f in (("rpc_file", side_file(tif_path, "RPC")),
                                         ("hdr_file", side_file(tif_path, "HDR"))) if f},
    }
