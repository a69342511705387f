"""The DSM GeoTIFF: Cloud-Optimized layout with a vertical CRS, nodata, mask and quality bands.

Bands (float32, nodata NaN):

1. ``height`` — metres, ellipsoidal or orthometric (the CRS says which);
2. ``mask`` — 0 void (nothing matched) or not seen by all three images, 1 matched,
   2 filled by interpolation;
3. ``pairs_agreeing`` — how many of the F–N, N–B, F–B heights agreed (0–3).

CRS: compound, the scene's projected CRS + a vertical CRS: ellipsoidal height on the datum's
ellipsoid, or, for orthometric heights, the geoid's (EGM96 → EPSG:5773, EGM2008 → EPSG:3855,
any other geoid a named one). All of it lives in the GeoTIFF keys (GeoTIFF 1.1), none in a side
file. Tiled 256 × 256, deflate, internal overviews (COG driver, :mod:`prismstation.io.cog`).
Tags: ``FILL_PERCENT`` (matched share of the seen cells), ``SEEN_CELLS``, ``POSTING_M``,
``HEIGHTS``. The file is written beside the target, read back and renamed over it
(:mod:`prismstation.io.atomic`: a failure leaves no file and raises a ``WriteError``); the
uncompressed GeoTIFF the COG is copied from (12 bytes a cell: ~0.6 GB for a 14,000 px scene at
5 m) is written in the system's temporary folder (``TMPDIR``), not beside the target.
"""
from __future__ import annotations

import numpy as np
import pyproj
import rasterio
from rasterio._err import CPLE_BaseError
from rasterio.crs import CRS
from rasterio.errors import RasterioError
from rasterio.transform import Affine
from rasterio.windows import Window

from prismstation.errors import PrismError
from prismstation.io.cog import write_cog
from prismstation.io.inputs import open_raster_file

NODATA = float("nan")   # what a plain read of band 1 shows as no height
BANDS = ("height", "mask", "pairs_agreeing")


def vertical_crs(crs, height_kind: str, geoid: str | None = None) -> CRS:
    """The 3-D (ellipsoidal) or compound (orthometric, through ``geoid``) CRS of a DSM."""
    h = pyproj.CRS.from_user_input(str(crs))
    if height_kind == "ellipsoidal":
        # GeoTIFF keys cannot hold a 3-D projected CRS (GDAL would put it in a side file);
        # a compound CRS whose vertical part names the ellipsoid can
        datum = h.geodetic_crs.datum.name if h.geodetic_crs else "ellipsoid"
        v = pyproj.CRS.from_wkt(
            f'VERTCRS["ellipsoidal height ({h.geodetic_crs.name if h.geodetic_crs else "ellipsoid"})",'
            f'VDATUM["{datum} ellipsoid"],CS[vertical,1],'
            'AXIS["ellipsoidal height (h)",up],LENGTHUNIT["metre",1]]')
    else:
        name = (geoid or "").lower()
        if "egm2008" in name or "egm08" in name:
            v = pyproj.CRS("EPSG:3855")
        elif "egm96" in name or "egm 96" in name:
            v = pyproj.CRS("EPSG:5773")
        else:
            v = pyproj.CRS.from_wkt(
                f'VERTCRS["height above the geoid ({geoid or "unnamed"})",'
                'VDATUM["geoid of the project"],CS[vertical,1],'
                'AXIS["gravity-related height (H)",up],LENGTHUNIT["metre",1]]')
    return CRS.from_wkt(pyproj.crs.CompoundCRS(f"{h.name} + {v.name}", [h, v]).to_wkt())


#: rows written at once
STRIP_ROWS = 1024


class DsmTiles:
    """The scratch copy of a DSM being written (:func:`write_dsm_tiles`), window by window:
    :meth:`write` puts a window's heights, mask and pairs agreeing, :meth:`read` gets a window
    back (a second pass: voids filled across windows)."""

    def __init__(self, ds):
        self.ds = ds

    def write(self, r0: int, c0: int, heights, mask, quality, seen) -> None:
        """Heights (float32, NaN void), ``mask`` and ``quality`` (uint8 or None: 0) of the window
        at row ``r0``, column ``c0``; bands 2 and 3 are NaN where not ``seen``."""
        h = np.asarray(heights, np.float32)
        window = Window(int(c0), int(r0), h.shape[1], h.shape[0])
        self.ds.write(np.where(np.isfinite(h), h, NODATA).astype(np.float32), 1, window=window)
        for i, band in ((2, mask), (3, quality)):
            v = np.zeros(h.shape, np.float32) if band is None else np.asarray(band, np.float32)
            self.ds.write(np.where(seen, v, NODATA).astype(np.float32), i, window=window)

    def read(self, r0: int, c0: int, rows: int, cols: int):
        """``(heights, mask, quality, seen)`` of a window written before (heights NaN void; mask
        and quality uint8, 0 where not seen)."""
        window = Window(int(c0), int(r0), int(cols), int(rows))
        h, m, q = (self.ds.read(i, window=window) for i in (1, 2, 3))
        seen = np.isfinite(m)
        return h, np.nan_to_num(m).astype(np.uint8), np.nan_to_num(q).astype(np.uint8), seen


def dsm_tags(matched: int, n_seen: int, posting_m: float, height_kind: str, heights_model=None) -> dict:
    """The DSM's GeoTIFF tags (module docstring) from its counts: cells matched among the
    ``n_seen`` cells every image sees."""
    tags = {"FILL_PERCENT": f"{100.0 * matched / n_seen if n_seen else 0.0:.2f}",
            "SEEN_CELLS": str(int(n_seen)), "POSTING_M": f"{posting_m:g}", "HEIGHTS": height_kind}
    if heights_model:
        tags["HEIGHT_MODEL"] = f"{heights_model['model']} ({heights_model['reason']})"
    return tags


def write_dsm_tiles(path, *, crs, transform, shape, height_kind: str, geoid: str | None = None,
                    fill, before_keep=None) -> None:
    """Write a DSM as a COG GeoTIFF at ``path`` window by window: ``fill(tiles)`` writes the
    :class:`DsmTiles` ``tiles`` (a grid of ``shape`` (rows, cols) on ``transform``, north-up, in
    ``crs`` with the vertical CRS of ``height_kind`` and ``geoid``) and returns the tags
    (:func:`dsm_tags`). Nothing grid-sized is held in memory; atomic as :func:`write_dsm`."""
    rows, cols = shape
    profile = dict(width=int(cols), height=int(rows), count=3, dtype="float32",
                   crs=vertical_crs(crs, height_kind, geoid),
                   transform=Affine(*tuple(transform)[:6]), nodata=NODATA, GEOTIFF_VERSION="1.1")

    def fill_scratch(ds):
        ds.update_tags(**fill(DsmTiles(ds)))
        for i, name in enumerate(BANDS, 1):
            ds.set_band_description(i, name)
    write_cog(path, profile, fill_scratch, before_keep=before_keep, what="dsm")


def write_dsm(path, dsm, *, before_keep=None) -> None:
    """Write ``dsm`` (:class:`prismstation.ops.dsm.Dsm`) as a COG GeoTIFF at ``path``,
    atomically (:func:`prismstation.io.cog.write_cog`); a failure is a
    :class:`~prismstation.errors.WriteError` (naming the scratch copy when the temporary folder
    is what failed). ``before_keep()``, when given, is called once the whole file is written and
    checked, before it replaces ``path``: whatever it raises (a cancel) leaves ``path`` as it was
    and no temporary file."""
    h = np.asarray(dsm.heights, np.float32)
    rows, cols = h.shape
    seen = np.isfinite(h) if dsm.seen is None else dsm.seen
    matched = int(((dsm.mask == 1) & seen).sum()) if dsm.mask is not None else int(np.isfinite(h).sum())

    def fill(tiles):
        # in strips of rows (no grid-sized copy in memory)
        for r0 in range(0, rows, STRIP_ROWS):
            rs = slice(r0, r0 + STRIP_ROWS)
            tiles.write(r0, 0, h[rs], None if dsm.mask is None else dsm.mask[rs],
                        None if dsm.quality is None else dsm.quality[rs], seen[rs])
        return dsm_tags(matched, int(seen.sum()), dsm.posting_m, dsm.height_kind, dsm.info.get("heights"))
    write_dsm_tiles(path, crs=dsm.crs, transform=dsm.transform, shape=(rows, cols), height_kind=dsm.height_kind,
                    geoid=dsm.geoid, fill=fill, before_keep=before_keep)


def read_dsm_info(path) -> dict:
    """Tags, band names, CRS (pyproj), block shape and overview factors of a written DSM."""
    with rasterio.open(path) as ds:
        return {"tags": ds.tags(), "bands": ds.descriptions, "crs": pyproj.CRS.from_wkt(ds.crs.to_wkt()),
                "blocks": ds.block_shapes[0], "overviews": ds.overviews(1), "nodata": ds.nodata,
                "shape": (ds.height, ds.width)}


def recorded_height_kind(path) -> str | None:
    """The kind of heights a raster says it holds — ``"ellipsoidal"``, ``"orthometric"`` — or
    None where it does not say (or cannot be read). A DSM written here says it twice (the
    ``HEIGHTS`` tag, the vertical CRS of :func:`vertical_crs`); another raster through its CRS:
    a vertical CRS is gravity-related (orthometric) unless its name or datum names an ellipsoid
    (GeoTIFF keys keep those, not the axis), a 3-D CRS with an ellipsoidal height axis is
    ellipsoidal; a 2-D CRS says nothing."""
    try:
        with open_raster_file(path, "DSM") as ds:  # (a typed path: a FIFO would hang the reader)
            tag, wkt = ds.tags().get("HEIGHTS"), ds.crs.to_wkt() if ds.crs else None
    except (PrismError, RasterioError, CPLE_BaseError, OSError):
        return None
    if tag in ("ellipsoidal", "orthometric"):
        return tag
    if not wkt:
        return None
    crs = pyproj.CRS.from_wkt(wkt)
    for part in crs.sub_crs_list if crs.is_compound else [crs]:
        if part.is_vertical:
            names = f"{part.name} {part.datum.name if part.datum else ''}".lower()
            return "ellipsoidal" if "ellipsoid" in names else "orthometric"
        if any("ellipsoidal height" in a.name.lower() for a in part.axis_info):
            return "ellipsoidal"
    return None
