"""Find and read the RPCs of an image, whichever way they come.

:func:`read_rpc` takes an image (or an RPC file) and returns a
:class:`prismstation.core.models.rpc.Rpc` in the image's own pixel frame. Looked for, in this order:

1. an OSSIM ``<stem>.geom`` beside the image (GDAL does not read it). When the image has a
   translation-only geotransform and no CRS, the image is a crop of the product the RPC
   describes and the geotransform gives the full-image position of the crop's top-left
   corner: a crop pixel ``(col, row)`` is full-image pixel ``(col + c, row + f)``, so the RPC
   is moved by ``(−c, −f)``;
2. JAXA's ``RPC-<id>.txt`` beside ``IMG-<id>.tif`` / ``IMG-<band>-<id>.tif`` (read here: GDAL's
   ALOS reader needs the product's ``summary.txt`` or ``HDR`` file as well);
3. ``<stem>.RPB``, ``<stem>_RPC.TXT``, ``RPC_<stem>.XML`` (DIMAP) beside the image, and
   ``RPC_<id>.XML`` beside a DIMAP product's first tile ``IMG_<id>_R1C1`` (other tiles are left
   to GDAL, which places them in the product through its ``DIM_<id>.XML``);
4. the RPCs GDAL finds (rasterio's ``ds.rpcs``): GeoTIFF RPC tags, NITF RPC00B, and side files
   of products GDAL recognises; a NITF ``RPC00A`` record is read here from GDAL's ``TRE``
   metadata domain (GDAL reorders its terms wrongly).

Side files are parsed here (not through GDAL) so that a bad file is reported with its line, and
so that an RPC00A order is recognised (GDAL reads ``.RPB`` and DIMAP RPC00A as RPC00B);
the tags and NITF RPC00B come from rasterio, which reads them well. No package beyond rasterio
is used: ``rpcm`` would add ``srtm4`` (SRTM tiles downloaded at run time) and ``shareloc``
numba and xarray for the few hundred lines this needs.
"""
from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

from prismstation.core.models.rpc import Rpc
from prismstation.errors import InputError, ModelError, RasterReadError
from prismstation.io.inputs import local_file, open_raster_file
from prismstation.io import rpc_formats as fmt

__all__ = ["read_rpc", "read_rpc_file", "find_rpc_files", "rpc_from_rasterio"]


def _kind_of(path: Path):
    """The parser for an RPC file recognised by its name, or None."""
    name = path.name.lower()
    if name.endswith(".geom"):
        return fmt.read_geom
    if name.endswith(".rpb"):
        return fmt.read_rpb
    if name.endswith("_rpc.txt"):
        return fmt.read_rpc_txt
    if name.startswith("rpc_") and name.endswith(".xml"):
        return fmt.read_dimap_xml
    if name.startswith("rpc-") and name.endswith(".txt"):
        return fmt.read_alos_txt
    return None


def read_rpc_file(path) -> Rpc:
    """Parse one RPC file, its format told by its name (``*.geom``, ``*.RPB``,
    ``*_RPC.TXT``, ``RPC_*.XML``, ``RPC-*.txt``); image coordinates as the file states them."""
    path = Path(path)
    reader = _kind_of(path)
    if reader is None:
        raise InputError("not an RPC file name this reader knows (*.geom, *.RPB, *_RPC.TXT, "
                         "RPC_*.XML, RPC-*.txt)", path)
    if not path.is_file():
        raise InputError("no such file", path)
    return reader(path)


def _sibling(directory: Path, name: str) -> Path | None:
    """``directory/name`` matched without regard to case (products come from Windows too)."""
    exact = directory / name
    if exact.is_file():
        return exact
    low = name.lower()
    try:
        return next((p for p in directory.iterdir() if p.name.lower() == low and p.is_file()), None)
    except OSError:
        return None


def find_rpc_files(image) -> list[Path]:
    """The RPC side files beside ``image``, in the order :func:`read_rpc` tries them."""
    image = Path(image)
    d, stem = image.parent, image.stem
    names = [f"{stem}.geom"]
    if stem.upper().startswith("IMG-"):
        rest = stem[4:]
        names += [f"RPC-{rest}.txt"]
        if len(rest) > 3 and rest[2] == "-":          # IMG-<band>-<id>
            names += [f"RPC-{rest[3:]}.txt"]
    names += [f"{stem}.RPB", f"{stem}_RPC.TXT", f"RPC_{stem}.XML"]
    m = re.fullmatch(r"IMG_(.+)_R1C1", stem, re.IGNORECASE)
    if m:                                   # the first tile of a DIMAP product
        names += [f"RPC_{m[1]}.XML"]
    found = (_sibling(d, n) for n in names)
    return [p for p in found if p is not None]


def rpc_from_rasterio(rpcs, source: str = "") -> Rpc:
    """A :class:`rasterio.rpc.RPC` as :class:`Rpc` (same conventions: GDAL's)."""
    try:
        return Rpc(rpcs.line_off, rpcs.samp_off, rpcs.lat_off, rpcs.long_off, rpcs.height_off,
                   rpcs.line_scale, rpcs.samp_scale, rpcs.lat_scale, rpcs.long_scale,
                   rpcs.height_scale, rpcs.line_num_coeff, rpcs.line_den_coeff,
                   rpcs.samp_num_coeff, rpcs.samp_den_coeff, source=source)
    except (ModelError, TypeError, ValueError) as exc:
        raise InputError(f"RPC metadata read by GDAL is unusable: {exc}", source or None) from None


def _crop_offset(image: Path) -> tuple[float, float] | None:
    """Full-image position ``(c, f)`` of a crop's top-left corner from a translation-only
    geotransform without CRS, else None."""
    try:
        with open_raster_file(image, "image") as ds:
            t, crs = ds.transform, ds.crs
    except (RasterReadError, InputError):
        return None
    if crs is None and (t.a, t.b, t.d, t.e) == (1.0, 0.0, 0.0, 1.0) and (t.c, t.f) != (0.0, 0.0):
        return float(t.c), float(t.f)
    return None


def read_rpc(path) -> Rpc:
    """The RPCs of an image (or of an RPC file given directly), in the image's pixel frame.

    Raises :class:`InputError` naming the file and, for side files, the line, when the RPCs
    are missing or bad.
    """
    path = local_file(path, "image")
    if _kind_of(path) is not None:
        return read_rpc_file(path)
    for side in find_rpc_files(path):
        rpc = read_rpc_file(side)
        if side.suffix.lower() == ".geom":
            off = _crop_offset(path)
            if off is not None:
                rpc = replace(rpc.shifted(-off[0], -off[1]), source=f"{rpc.source}, crop at "
                              f"({off[0]:g}, {off[1]:g}) of the product")
        return rpc
    try:
        with open_raster_file(path, "image") as ds:
            rpcs = ds.rpcs
            driver = ds.driver
            records = ds.tags(ns="TRE") if "TRE" in ds.tag_namespaces() else {}
    except RasterReadError as exc:
        raise InputError(str(exc).removeprefix(f"{path}: "), path) from None
    if "RPC00A" in records and "RPC00B" not in records:
        # GDAL reorders RPC00A's quadratic terms the wrong way round (LPH, L², P², H² as
        # P², H², LPH, L²): tens of pixels off; the record is read here
        return fmt.read_nitf_tre("RPC00A", records["RPC00A"], path)
    if rpcs is None:
        raise InputError("no RPCs found: none in the file's metadata (GeoTIFF tags, NITF "
                         "RPC00B or RPC00A) and no side file (.geom, .RPB, _RPC.TXT, RPC_*.XML, "
                         "RPC-*.txt) beside it", path)
    return rpc_from_rasterio(rpcs, f"{path.name} ({driver} metadata through GDAL)")
