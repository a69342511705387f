"""What every point file shares: :class:`PointFile`, CRS texts as other tools write them, the
horizontal conversion of ground points, and the lon/lat column-order check; a CRS in words
(:func:`crs_name`) and the conversion of map coordinates between two CRSs (:class:`Reprojection`).

CRS texts (:func:`parse_crs`): anything pyproj reads (``EPSG:32617``, ``epsg:4326``, proj
strings, WKT), a proj string in quotes (``'+proj=utm +zone=17 ...'``), and the OpenDroneMap
spellings ``WGS84 UTM 17N`` / ``WGS84 UTM 17 S`` and ``WGS84 longlat`` / ``WGS84 lonlat`` /
``WGS84 latlon`` (geographic WGS 84; ``latlon`` says the file lists latitude first).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace

from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError, ProjError

from prismstation.errors import InputError

_UTM_WORDS = re.compile(r"^\s*WGS\s*84\s+UTM\s+(\d{1,2})\s*([NS])\s*$", re.IGNORECASE)
_GEO_WORDS = re.compile(r"^\s*WGS\s*84\s+(lon(?:g)?\s*lat|lat\s*lon(?:g)?)\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class PointFile:
    """Ground points and image measurements read from (or to write to) one file.

    Attributes
    ----------
    points : tuple of GroundPoint
        ``E``, ``N`` in units of ``crs`` (x = easting or longitude, y = northing or latitude);
        ``H`` in metres.
    measurements : tuple of Measurement
        Pixel coordinates, origin at the top-left corner of the top-left pixel; ``view`` is the
        image name.
    crs : str or None
        The CRS as the file states it (``"EPSG:32617"``, a proj4 string, WKT), or ``None``.
    format : str
        One of ``FORMATS`` of :mod:`prismstation.io.pointfiles`.
    header : str or None
        The file's own CRS line, written back unchanged when the CRS was not changed.
    warnings : tuple of str
        What the reader guessed and the user should know (e.g. swapped lat/lon columns).
    """

    points: tuple = ()
    measurements: tuple = ()
    crs: str | None = None
    format: str = "csv"
    header: str | None = field(default=None, compare=False)
    warnings: tuple = field(default=(), compare=False)


def parse_crs(text: str, path=None, line: int | None = None) -> CRS:
    """A pyproj CRS from a CRS text (see the module docstring); InputError when unknown."""
    text = text.strip().strip("'\"").strip()
    m = _UTM_WORDS.match(text)
    if m:
        zone, hemi = int(m.group(1)), m.group(2).upper()
        if not 1 <= zone <= 60:
            raise InputError(f"UTM zone {zone} is not between 1 and 60", path, line)
        return CRS.from_epsg((32600 if hemi == "N" else 32700) + zone)
    if _GEO_WORDS.match(text):
        return CRS.from_epsg(4326)
    try:
        return CRS.from_user_input(text)
    except CRSError as exc:
        raise InputError(f"unknown coordinate system {text!r} ({exc})", path, line) from None


def latitude_first(text: str | None) -> bool:
    """True when the CRS text says the file lists latitude before longitude (``WGS84 latlon``)."""
    m = _GEO_WORDS.match((text or "").strip().strip("'\""))
    return bool(m) and m.group(1).lower().startswith("lat")


def metres_per_unit(crs_text: str | None) -> float:
    """Metres per unit of the first axis of ``crs_text`` (1 for geographic or unknown CRSs)."""
    if not crs_text:
        return 1.0
    crs = parse_crs(crs_text)
    if crs.is_geographic:
        return 1.0
    factor = crs.axis_info[0].unit_conversion_factor if crs.axis_info else 1.0
    return float(factor or 1.0)


def height_metres_per_unit(crs_text: str, source=None) -> float:
    """Metres per unit of the heights of a raster whose CRS is ``crs_text`` (WKT): its vertical
    CRS's unit when it has one (a compound CRS), else 1 — unless its map unit is not the metre
    (US survey feet…): such a DEM says nothing of its heights' unit (usually feet, not always),
    and a guess would bias every height by a factor of 3.28, so it is an :class:`InputError`
    naming ``source``."""
    crs = CRS.from_user_input(crs_text)
    if crs.is_compound and len(crs.sub_crs_list) > 1 and crs.sub_crs_list[1].axis_info:
        return float(crs.sub_crs_list[1].axis_info[0].unit_conversion_factor or 1.0)
    if crs.is_geographic or not crs.axis_info:
        return 1.0
    axis = crs.axis_info[0]
    if abs((axis.unit_conversion_factor or 1.0) - 1.0) > 1e-12:
        raise InputError(f"the CRS is in {axis.unit_name} and the file does not say in what unit its heights "
                         "are (no vertical CRS): give a DEM in metres, or one whose CRS names its vertical unit",
                         source)
    return 1.0


def lonlat_order(points, lines, path, crs_text, names=("x", "y")):
    """``(points, warnings)``: geographic ``points`` (E = longitude, N = latitude) with the two
    columns swapped when the values say the file has them the other way round.

    ``lines``: the 1-based file line of each point; ``names``: how the messages call the columns
    read as longitude, latitude. A value |v| > 90 read as a latitude is a longitude: when the
    other column has no such value, the columns are swapped and a warning says so. When both
    columns have |v| > 90, or a longitude is outside [-180, 360], the line is named in an
    InputError. Without |v| > 90 in the latitude column the order is ambiguous and stays as the
    file says. Projected CRSs are returned unchanged.
    """
    if not points or not crs_text or not parse_crs(crs_text).is_geographic:
        return list(points), []
    bad_lat = [(no, p.N) for no, p in zip(lines, points) if abs(p.N) > 90]
    if not bad_lat:
        warnings = []
    elif all(abs(p.E) <= 90 for p in points):
        no, v = bad_lat[0]
        warnings = [f"{path}: {names[1]} holds longitudes (e.g. {v} on line {no}): "
                    f"read {names[0]} as latitude and {names[1]} as longitude"]
        points = [replace(p, E=p.N, N=p.E, extra=_swap_sigmas(p.extra)) for p in points]
    else:
        no, v = bad_lat[0]
        raise InputError(f"latitude ({names[1]}) {v} is outside [-90, 90], and {names[0]} holds "
                         f"values beyond ±90 too", path, no)
    for no, p in zip(lines, points):
        if not -180 <= p.E <= 360:
            raise InputError(f"longitude ({names[0]}) {p.E} is outside [-180, 360]",
                             path, no)
    return list(points), warnings


def _swap_sigmas(extra: dict) -> dict:
    """``extra`` with the σ of latitude and longitude exchanged (ASP files carry both)."""
    if "sigma_lat" in extra and "sigma_lon" in extra:
        return {**extra, "sigma_lat": extra["sigma_lon"], "sigma_lon": extra["sigma_lat"]}
    return extra


def convert_point_file(pf: PointFile, to_crs: str) -> PointFile:
    """Ground points transformed horizontally to ``to_crs`` with pyproj (``always_xy``).

    Heights are kept (metres, same kind); a vertical datum change is not made here.
    """
    if not pf.crs:
        raise InputError("the input names no coordinate system; give it with --crs")
    src, dst = parse_crs(pf.crs), parse_crs(to_crs)
    try:
        tr = Transformer.from_crs(src, dst, always_xy=True)
    except ProjError as exc:
        raise InputError(f"cannot convert from {pf.crs[:60]!r} to {to_crs!r}: {exc}") from None
    pts = []
    for p in pf.points:
        e, n = tr.transform(p.E, p.N)
        if not (math.isfinite(e) and math.isfinite(n)):
            raise InputError(f"point {p.id!r} cannot be transformed to {to_crs}")
        pts.append(replace(p, E=float(e), N=float(n)))
    return replace(pf, points=tuple(pts), crs=to_crs, header=None)


def crs_name(text) -> str:
    """A CRS as an operator reads it — ``WGS 84 / UTM zone 29N (EPSG:32629)`` — from any
    definition (WKT, ``EPSG:…``, PROJ string); the text itself, shortened, when PROJ cannot read it."""
    try:
        crs = CRS.from_user_input(text)
    except (CRSError, TypeError, ValueError):
        t = " ".join(str(text).split())
        return t if len(t) <= 60 else t[:57] + "…"
    code = crs.to_epsg(min_confidence=70)
    return f"{crs.name} (EPSG:{code})" if code else crs.name


class Reprojection:
    """Map coordinates of CRS ``source`` to CRS ``target`` (default ``source``) and back, x =
    easting (or longitude): ``forward(x, y)``, ``backward(x, y)`` → ``(x, y)`` arrays;
    ``same`` when the two are one CRS; ``target_wkt``, ``target_text`` the target's WKT and its
    shortest definition. A CRS PROJ does not know is an :class:`InputError`."""

    def __init__(self, source, target=None):
        try:
            src = CRS.from_user_input(source)
            dst = src if target is None else CRS.from_user_input(target)
        except CRSError as exc:
            raise InputError(f"unknown CRS ({exc})") from None
        self.same = dst == src
        self.target_wkt, self.target_text = dst.to_wkt(), dst.to_string()
        self._fw = Transformer.from_crs(src, dst, always_xy=True)
        self._bw = Transformer.from_crs(dst, src, always_xy=True)

    def forward(self, x, y):
        return self._fw.transform(x, y)

    def backward(self, x, y):
        return self._bw.transform(x, y)
