"""The one door for the files a user or a project names: regular local files, in the formats
the workstation reads, that reach nothing else.

A project file is data from anywhere. Every file it names (scene, images, DEMs, geoid grid) and
every table or raster a command reads passes :func:`local_file`: a path, not a GDAL virtual file
system (``/vsicurl/…``, ``/vsizip/…``) nor a URL; a regular file, not a FIFO, a device
(``/dev/zero``), a folder or a symbolic-link loop (a FIFO or a device would hang the reader or
fill the memory). Rasters are opened by :func:`open_raster_file` only, with the GDAL drivers of
:data:`RASTER_DRIVERS`; a VRT is opened only when every file it references is itself such a
local file (checked recursively) and it holds no pixel-function code. :data:`GDAL_SAFE_OPTIONS`,
set by :func:`prismstation.io.raster.gdal_env` at every entry point, keeps GDAL itself off the
network and from running code should a path get past the checks.
"""
from __future__ import annotations

import os
import stat
import warnings
from pathlib import Path

from prismstation.errors import InputError, RasterReadError
from prismstation.io.atomic import cause_text

#: GDAL drivers of the rasters the workstation reads: images (GeoTIFF, JPEG 2000, NITF, PNG,
#: JPEG, Erdas), DEMs (GeoTIFF, SRTM .hgt, DTED, ASCII grids, ENVI/EHdr), geoid grids (GTX)
RASTER_DRIVERS = ("GTiff", "VRT", "SRTMHGT", "HFA", "JP2OpenJPEG", "NITF", "PNG", "JPEG", "GTX",
                  "AAIGrid", "EHdr", "ENVI", "DTED")

#: GDAL configuration that keeps GDAL off the network and from running code a file holds
GDAL_SAFE_OPTIONS = {
    "CPL_VSIL_CURL_ALLOWED_EXTENSIONS": ".prismstation-reads-no-network",  # /vsicurl/ sees no file
    "GDAL_HTTP_MAX_RETRY": "0",
    "GDAL_HTTP_TIMEOUT": "1",
    "GDAL_VRT_ENABLE_PYTHON": "NO",            # a VRT's pixel function never runs Python
    "GDAL_VRT_ENABLE_RAWRASTERBAND": "NO",     # nor reads raw bytes of any file it names
    "GDAL_ENABLE_DEPRECATED_DRIVER_DODS": "NO",
}

_VSI_PREFIXES = ("/vsi", "\\vsi")
_MAX_VRT_DEPTH = 8


def _text(path) -> str:
    return os.fspath(path) if not isinstance(path, str) else path


def _not_local(path) -> tuple[str | None, Path | None]:
    """``(why, None)`` when ``path`` is no regular local file (why: ``"is a FIFO"``…), else
    ``(None, Path)``."""
    text = _text(path)
    low = text.strip().lower()
    if low.startswith(_VSI_PREFIXES):
        return "is a GDAL virtual file system path, not a local file", None
    if "://" in low or low.startswith(("http:", "https:", "ftp:")):
        return "is a URL, not a local file", None
    p = Path(text)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return "not found", None
    except OSError as exc:  # ELOOP (a symbolic-link loop), ENAMETOOLONG, EACCES…
        return f"cannot be read ({exc.strerror or exc})", None
    except ValueError:  # a NUL byte
        return "is not a usable file path", None
    if not stat.S_ISREG(st.st_mode):
        kind = ("a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
                else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        return f"is {kind}, not a file", None
    return None, p


def local_file(path, what: str = "file") -> Path:
    """``path`` as a :class:`Path` when it names a regular local file; else an
    :class:`InputError` naming it and what it is instead (not found, a folder, a FIFO, a
    device, a symbolic-link loop, a GDAL virtual file system or a URL; prismstation reads
    only local files)."""
    why, p = _not_local(path)
    if why is not None:
        raise InputError(f"{what} {why}", _text(path)[:200])
    return p


def _vrt_sources(path: Path, what: str, depth: int = 0) -> None:
    """Every file a VRT names is a local file of its own (recursively); no pixel-function code."""
    import xml.etree.ElementTree as ET
    if depth > _MAX_VRT_DEPTH:
        raise InputError(f"{what}: VRTs nested deeper than {_MAX_VRT_DEPTH}", path)
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError, RecursionError) as exc:
        raise InputError(f"{what}: not a readable VRT ({exc})", path) from None
    for el in root.iter():
        tag = el.tag if isinstance(el.tag, str) else ""
        if tag in ("PixelFunctionCode", "PixelFunctionLanguage") and (el.text or "").strip():
            raise InputError(f"{what}: the VRT holds pixel-function code, which prismstation does not run", path)
        if tag in ("SourceFilename", "SourceDataset", "SourceDataSet"):
            name = (el.text or "").strip()
            if not name:
                continue
            relative = el.get("relativeToVRT", el.get("relativetoVRT", "0")) == "1"
            local = relative and not name.lower().startswith(_VSI_PREFIXES) and "://" not in name
            why, src = _not_local(Path(path).parent / name if local else name)
            if why is not None:
                raise InputError(f"{what}: the VRT names {name[:120]!r}, which {why} "
                                 "(prismstation reads only local files)", path)
            if _is_vrt(src):
                _vrt_sources(src, what, depth + 1)


def _is_vrt(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            head = fh.read(512).lstrip()
    except OSError:
        return False
    return head.startswith(b"<VRTDataset") or (head.startswith(b"<?xml") and b"<VRTDataset" in head)


def check_raster_file(path, what: str = "raster") -> Path:
    """:func:`local_file`, and for a VRT every file it references (see the module docstring)."""
    p = local_file(path, what)
    if _is_vrt(p):
        _vrt_sources(p, what)
    return p


def open_raster_file(path, what: str = "raster"):
    """The rasterio dataset of a raster a user or a project names (:func:`check_raster_file`,
    then opened with :data:`RASTER_DRIVERS` only). A file that fails the checks is an
    :class:`InputError`; one GDAL cannot open a :class:`RasterReadError`, both naming the file."""
    from rasterio._path import _UnparsedPath
    from rasterio.env import env_ctx_if_needed
    from rasterio.errors import NotGeoreferencedWarning
    from rasterio.io import DatasetReader

    p = check_raster_file(path, what)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            # rasterio.open takes one driver name; its reader passes a list to GDALOpenEx as
            # the drivers allowed to open the file (a local XML file of the WMS driver, say,
            # would otherwise fetch from its server)
            with env_ctx_if_needed():  # GDAL's drivers registered (rasterio.open does so)
                return DatasetReader(_UnparsedPath(str(p)), driver=list(RASTER_DRIVERS))
    except Exception as exc:  # rasterio's and GDAL's errors, OSError: the file is unusable
        raise RasterReadError(f"{p}: cannot open {what} as a raster ({cause_text(exc, str(p))})") from None
