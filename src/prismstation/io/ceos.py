"""JAXA ALOS PRISM level 1B2 products in CEOS format (``VOL-``, ``LED-``, ``IMG-``, ``TRL-`` files).

Byte layout relied on (offsets are 0-based from the start of a record; every CEOS record starts
with a 12-byte header whose bytes 8-11 hold the record length, big-endian). The field positions
agree between ESA SNAP's ALOS reader (``beam-alos-reader``: ``Ancillary1Record``,
``Ancillary3Record``, ``BaseImageFileDescriptorRecord``, ``ImageRecord``) and ASF MapReady
(``code_ceos.c``: ``Code_AMPR``, ``Code_PPDR``, ``Code_ALOS_optical_IOF``):

Leader file ``LED-*``: records in the order file descriptor, scene header, map projection
ancillary (SNAP "ancillary 1"), radiometric ancillary, platform position ("ancillary 3"), ...

Map projection ancillary record (ASCII fields unless noted)::

    92  I4   hemisphere, 0 = north, 1 = south
    96  I12  UTM zone
    140 F16  scene centre northing (km)          156 F16 scene centre easting (km)
    540 F16  1B2 inter-pixel distance (m)        556 F16 1B2 inter-line distance (m)
    668 F16  nominal satellite altitude (km)     700 F16 nominal heading
    1916 6 x B8 (big-endian IEEE doubles) a, b, c, d, e, f of the "F4" map -> image affine

Our reading of the F4 coefficients (Gonçalves 2008, eq. 1): ``x' = a*x + b*y + e``,
``y' = c*x + d*y + f`` with map ``x`` = (E - 500 km) and ``y`` = (N - false northing) in
kilometres (false northing 10 000 km in the southern hemisphere, else 0), and ``(x', y')`` the
image address (pixel, line) counted from 1 at the centre of the first pixel, as CEOS numbers
pixels. In docs/model.md pixels (origin at the top-left corner) that address is ``(x' - 0.5, y' - 0.5)``.

Platform position record::

    140 I4 number of state vectors     144 I4 year   148 I4 month   152 I4 day
    160 F22 seconds of day of the first vector   182 F22 interval (s)
    386 + 132 k: position x, y, z (m), velocity x, y, z (m/s), 6 x F22, Earth-fixed (ECEF)

Image file ``IMG-*`` descriptor record::

    180 I6 number of image records   186 I6 image record length   216 I4 bits per pixel
    236 I8 lines                     248 I8 pixels per line
    280 I4 bytes before the pixels in a record (record header + prefix)
    284 I8 bytes of pixel data       292 I4 suffix bytes

``summary.txt``: ``Key="value"`` lines (GDAL's ALOS metadata reader): ``Scs_SceneID``,
``Pds_ProductID``, ``Img_SceneCenterDateTime`` (``YYYYMMDD HH:MM:SS.sss``), corner coordinates
``Img_ImageScene{LeftTop,...}{Latitude,Longitude}``.
"""
from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from pyproj import Transformer

from prismstation.errors import InputError
from prismstation.io.atomic import atomic_path, raster_check

NOMINAL_ALTITUDE_M = 691650.0
"""ALOS nominal orbit altitude (m), used when a product gives none."""
PRISM_TILT_DEG = 23.8
"""Along-track tilt of PRISM's forward and backward telescopes at the sensor (degrees)."""
EARTH_RADIUS_M = 6371000.0
CEOS_FIRST_PIXEL = 1.0
"""CEOS image addresses count from 1 at the centre of the first pixel."""


@dataclass(frozen=True)
class StateVectors:
    """Satellite state vectors: ``times`` (n,) UTC datetimes, ``pos`` (n, 3) m, ``vel`` (n, 3) m/s,
    Earth-fixed (ECEF, WGS84/ITRF axes)."""

    times: tuple
    pos: np.ndarray
    vel: np.ndarray

    def at(self, t: datetime) -> np.ndarray:
        """ECEF position (m) at ``t`` by cubic Hermite interpolation of positions and velocities."""
        secs = np.array([(s - self.times[0]).total_seconds() for s in self.times])
        x = (t - self.times[0]).total_seconds()
        i = int(np.clip(np.searchsorted(secs, x) - 1, 0, len(secs) - 2))
        h = secs[i + 1] - secs[i]
        s = (x - secs[i]) / h
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return (h00 * self.pos[i] + h10 * h * self.vel[i] + h01 * self.pos[i + 1]
                + h11 * h * self.vel[i + 1])


@dataclass(frozen=True)
class CeosView:
    """What one CEOS 1B2 view holds, in our conventions.

    ``map_to_image`` is ``[A1..A6]`` with ``x = A1*E + A2*N + A5``, ``y = A3*E + A4*N + A6``
    (E, N metres of ``crs``; x, y docs/model.md pixels). ``f4`` keeps the file's a..f as read.
    """

    view: str
    image_file: Path
    width: int
    height: int
    bits: int
    crs: str
    map_to_image: tuple
    f4: tuple
    pixel_size_m: float
    line_spacing_m: float
    altitude_m: float | None
    heading: float | None
    centre_en: tuple | None
    state_vectors: StateVectors | None
    summary: dict = field(default_factory=dict)
    scene_id: str = ""
    product_id: str = ""


# --------------------------------------------------------------------------- record access


def read_records(path) -> list[bytes]:
    """The records of a CEOS file, split by the length in each 12-byte header."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    records, pos = [], 0
    while pos < len(data):
        if len(data) - pos < 12:
            raise InputError(f"truncated record header at byte {pos}", path)
        length = struct.unpack(">I", data[pos + 8:pos + 12])[0]
        if length < 12 or pos + length > len(data):
            raise InputError(f"record {len(records) + 1} at byte {pos} claims length {length}, "
                             f"but the file has {len(data) - pos} bytes left", path)
        records.append(data[pos:pos + length])
        pos += length
    return records


def _text(rec: bytes, off: int, size: int) -> str:
    return rec[off:off + size].decode("ascii", "replace").strip()


def _num(rec: bytes, off: int, size: int, what: str, path, rec_no: int, *, optional=False):
    text = _text(rec, off, size)
    if not text:
        if optional:
            return None
        raise InputError(f"record {rec_no}: {what} (bytes {off + 1}-{off + size}) is blank", path)
    try:
        value = float(text.replace("D", "E"))
    except ValueError:
        raise InputError(f"record {rec_no}: {what} (bytes {off + 1}-{off + size}) is "
                         f"{text!r}, not a number", path) from None
    if not math.isfinite(value):
        raise InputError(f"record {rec_no}: {what} is not finite", path)
    return value


# --------------------------------------------------------------------------- leader


def f4_to_map_to_image(f4, zone_south: bool) -> tuple:
    """``map_to_image`` [A1..A6] (metres of UTM, docs/model.md pixels) from the F4 a..f (km, CEOS)."""
    a, b, c, d, e, f = (float(v) for v in f4)
    fe, fn = 500000.0, (10000000.0 if zone_south else 0.0)
    shift = CEOS_FIRST_PIXEL - 0.5
    return (a / 1000.0, b / 1000.0, c / 1000.0, d / 1000.0,
            e - shift - (a * fe + b * fn) / 1000.0, f - shift - (c * fe + d * fn) / 1000.0)


def read_leader(path) -> dict:
    """Map projection and platform position data of a 1B2 leader file (see module docstring)."""
    path = Path(path)
    recs = read_records(path)
    if len(recs) < 3:
        raise InputError(f"a leader file needs at least 3 records (descriptor, scene header, "
                         f"map projection); found {len(recs)}", path)
    mp = recs[2]
    if len(mp) < 1964:
        raise InputError(f"record 3 (map projection ancillary) has {len(mp)} bytes; the F4 "
                         "coefficients need 1964", path)
    hemi = _num(mp, 92, 4, "hemisphere", path, 3)
    zone = _num(mp, 96, 12, "UTM zone", path, 3)
    if hemi not in (0, 1) or not (1 <= zone <= 60 and zone == int(zone)):
        raise InputError(f"record 3: UTM zone {zone:g} / hemisphere {hemi:g} are not a UTM zone "
                         "(1-60) and 0 (north) or 1 (south); only UTM products are supported", path)
    f4 = struct.unpack(">6d", mp[1916:1964])
    if not all(math.isfinite(v) for v in f4) or abs(f4[0] * f4[3] - f4[1] * f4[2]) < 1e-12:
        raise InputError("record 3: the F4 map-to-image coefficients (bytes 1917-1964) are "
                         f"not an invertible affine: {f4}", path)
    north = _num(mp, 140, 16, "scene centre northing", path, 3, optional=True)
    east = _num(mp, 156, 16, "scene centre easting", path, 3, optional=True)
    alt = _num(mp, 668, 16, "nominal satellite altitude", path, 3, optional=True)
    out = {
        "south": hemi == 1, "zone": int(zone), "crs": f"EPSG:{(32700 if hemi else 32600) + int(zone)}",
        "f4": f4, "pixel_size_m": _num(mp, 540, 16, "inter-pixel distance", path, 3),
        "line_spacing_m": _num(mp, 556, 16, "inter-line distance", path, 3),
        "altitude_m": None if alt is None else (alt * 1000.0 if alt < 10000 else alt),
        "heading": _num(mp, 700, 16, "heading", path, 3, optional=True),
        "centre_en": None if north is None or east is None else (east * 1000.0, north * 1000.0),
        "state_vectors": None,
    }
    if len(recs) >= 5:
        out["state_vectors"] = _state_vectors(recs[4], path)
    return out


def _state_vectors(rec: bytes, path) -> StateVectors | None:
    n = _num(rec, 140, 4, "number of state vectors", path, 5, optional=True)
    if not n:
        return None
    n = int(n)
    if len(rec) < 386 + 132 * n:
        raise InputError(f"record 5 (platform position) is too short for {n} state vectors", path)
    y, mo, d = (int(_num(rec, o, 4, w, path, 5)) for o, w in ((144, "year"), (148, "month"),
                                                             (152, "day")))
    sec = _num(rec, 160, 22, "time of the first vector", path, 5)
    step = _num(rec, 182, 22, "vector interval", path, 5)
    try:
        t0 = datetime(y, mo, d, tzinfo=timezone.utc) + timedelta(seconds=sec)
    except (ValueError, OverflowError):
        raise InputError(f"record 5: {y}-{mo}-{d} + {sec} s is not a date", path) from None
    vals = np.array([[_num(rec, 386 + 132 * k + 22 * j, 22, "state vector", path, 5)
                      for j in range(6)] for k in range(n)])
    try:
        times = tuple(t0 + timedelta(seconds=step * k) for k in range(n))
    except OverflowError:
        raise InputError(f"record 5: {n} vectors every {step} s run past the last date", path) from None
    if n < 2 or step <= 0:
        raise InputError("record 5: need two or more state vectors at a positive interval", path)
    return StateVectors(times, vals[:, :3], vals[:, 3:])


# --------------------------------------------------------------------------- summary and image


def read_summary(path) -> dict:
    """``Key="value"`` lines of a JAXA ``summary.txt`` (quotes removed)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="latin-1").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    out = {}
    for no, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if "=" not in text:
            raise InputError(f'expected Key="value", found {text[:40]!r}', path, no)
        key, value = text.split("=", 1)
        out[key.strip()] = value.strip().strip('"')
    return out


def summary_time(summary: dict, key: str, path=None) -> datetime | None:
    """A summary date-time (``YYYYMMDD HH:MM:SS.sss``) as an aware UTC datetime, or None."""
    text = summary.get(key)
    if not text:
        return None
    for fmt in ("%Y%m%d %H:%M:%S.%f", "%Y%m%d %H:%M:%S"):
        try:
            return datetime.strptime(text, fmt).replace(tzinfo=timezone.utc)
        except ValueError:
            pass
    raise InputError(f"{key}={text!r} is not YYYYMMDD HH:MM:SS.sss", path)


def read_image_descriptor(path) -> dict:
    """Sizes of a CEOS ``IMG-`` file from its descriptor record (see module docstring)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(12)
            if len(head) < 12:
                raise InputError("not a CEOS image file (shorter than a record header)", path)
            length = struct.unpack(">I", head[8:12])[0]
            if length < 12:
                raise InputError(f"the descriptor record claims {length} bytes, less than its header", path)
            rec = head + fh.read(length - 12)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    if len(rec) < 296:
        raise InputError("the image file descriptor record is shorter than 296 bytes", path)
    get = lambda o, s, w: int(_num(rec, o, s, w, path, 1))  # noqa: E731
    d = {"header_len": len(rec), "n_records": get(180, 6, "number of image records"),
         "record_len": get(186, 6, "image record length"), "bits": get(216, 4, "bits per pixel"),
         "lines": get(236, 8, "number of lines"), "pixels": get(248, 8, "pixels per line"),
         "prefix": get(280, 4, "prefix bytes"), "data_bytes": get(284, 8, "image data bytes")}
    if min(d["record_len"], d["lines"], d["pixels"]) < 1 or min(d["prefix"], d["n_records"]) < 0:
        raise InputError(f"the descriptor gives {d['lines']} lines of {d['pixels']} pixels in records "
                         f"of {d['record_len']} bytes after {d['prefix']} prefix bytes", path)
    if d["bits"] not in (8, 16):
        raise InputError(f"{d['bits']} bits per pixel: only 8 and 16 are supported", path)
    if d["prefix"] + d["pixels"] * d["bits"] // 8 > d["record_len"]:
        raise InputError(f"{d['pixels']} pixels after {d['prefix']} prefix bytes do not fit in "
                         f"records of {d['record_len']} bytes", path)
    size = path.stat().st_size
    if d["header_len"] + d["lines"] * d["record_len"] > size:
        raise InputError(f"{d['lines']} lines of {d['record_len']} bytes need "
                         f"{d['header_len'] + d['lines'] * d['record_len']} bytes; the file has "
                         f"{size}", path)
    return d


def image_array(path, desc: dict | None = None) -> np.ndarray:
    """Pixels of a CEOS image file as a read-only memory map, shape (lines, pixels)."""
    desc = desc or read_image_descriptor(path)
    dtype = np.dtype(">u2") if desc["bits"] == 16 else np.dtype("u1")
    rows = np.memmap(path, dtype="u1", mode="r", offset=desc["header_len"],
                     shape=(desc["lines"], desc["record_len"]))
    start = desc["prefix"]
    return rows[:, start:start + desc["pixels"] * dtype.itemsize].view(dtype)


def write_geotiff(img_path, tif_path, crs: str, map_to_image, desc: dict | None = None,
                  block_lines: int = 1024) -> Path:
    """Copy a CEOS image into a tiled GeoTIFF whose geotransform is the inverse of
    ``map_to_image`` (so both describe the same placement); written in strips of lines."""
    import rasterio
    from rasterio.transform import Affine
    from rasterio.windows import Window

    desc = desc or read_image_descriptor(img_path)
    arr = image_array(img_path, desc)
    a1, a2, a3, a4, a5, a6 = map_to_image
    inv = ~Affine(a1, a2, a5, a3, a4, a6)
    dtype = "uint16" if desc["bits"] == 16 else "uint8"
    tif_path = Path(tif_path)
    profile = dict(driver="GTiff", width=desc["pixels"], height=desc["lines"], count=1,
                   dtype=dtype, crs=crs, transform=inv, tiled=True, blockxsize=256,
                   blockysize=256, compress="deflate")
    # atomic: a failure is a WriteError naming the copy, and leaves no file
    with atomic_path(tif_path, check=raster_check(desc["pixels"], desc["lines"], 1)) as tmp:
        with rasterio.open(tmp, "w", **profile) as dst:
            for r0 in range(0, desc["lines"], block_lines):
                r1 = min(desc["lines"], r0 + block_lines)
                dst.write(np.asarray(arr[r0:r1], dtype=dtype), 1,
                          window=Window(0, r0, desc["pixels"], r1 - r0))
    return tif_path


# --------------------------------------------------------------------------- geometry helpers


def ground_angle_deg(sensor_tilt_deg: float, altitude_m: float) -> float:
    """Viewing angle at the ground (spherical Earth) of a ray tilted ``sensor_tilt_deg`` from the
    nadir at height ``altitude_m``: ``sin(theta) = (R + H) / R * sin(tilt)``."""
    s = (EARTH_RADIUS_M + altitude_m) / EARTH_RADIUS_M * math.sin(math.radians(sensor_tilt_deg))
    return math.degrees(math.asin(min(1.0, s)))


def incidence_deg(sat_ecef, crs: str, e: float, n: float) -> float:
    """Angle at ground point (E, N, h = 0) between the ellipsoid normal and the satellite
    (NaN where the point or the satellite position is not finite)."""
    lon, lat = Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(e, n)
    if not (math.isfinite(lon) and math.isfinite(lat)):
        return math.nan
    g = np.array(Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
                 .transform(lon, lat, 0.0))
    lo, la = math.radians(lon), math.radians(lat)
    normal = np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    ray = np.asarray(sat_ecef, dtype=float) - g
    norm = float(np.linalg.norm(ray))
    if not (math.isfinite(norm) and norm > 0):
        return math.nan
    return math.degrees(math.acos(max(-1.0, min(1.0, float(ray @ normal) / norm))))


def sub_satellite_track(sv: StateVectors, crs: str, t_mid: datetime, half_span_s: float = 30.0,
                        step_s: float = 5.0):
    """Sub-satellite points (geodetic nadir, in ``crs``) from ``t_mid - half_span_s`` to
    ``t_mid + half_span_s`` in flight (time) order, as a list of [E, N]; also the mean height."""
    to_geo = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    to_map = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    t_first, t_last = sv.times[0], sv.times[-1]
    pts, heights = [], []
    for k in np.arange(-half_span_s, half_span_s + 1e-9, step_s):
        t = t_mid + timedelta(seconds=float(k))
        if not t_first <= t <= t_last:
            continue
        lon, lat, h = to_geo.transform(*sv.at(t))
        e, n = to_map.transform(lon, lat)
        pts.append([float(e), float(n)])
        heights.append(float(h))
    return pts, (float(np.mean(heights)) if heights else None)


def view_letter(name: str) -> str | None:
    """``N``, ``F`` or ``B`` from a PRISM product id or file name (``..._UN``, ``_UF``, ``_UB``;
    ``_UW``, the wide nadir mode, is ``N``)."""
    m = re.search(r"_U([NFBW])(?![A-Za-z])", name)
    if not m:
        m = re.search(r"ALPSM([NFBW])", name)
    return None if not m else ("N" if m.group(1) == "W" else m.group(1))


def read_ceos_view(led_path, summary_path=None) -> CeosView:
    """Read one view: the leader ``led_path``, its ``IMG-`` file beside it and, if given, its
    ``summary.txt``."""
    led_path = Path(led_path)
    base = led_path.name[4:]
    img = led_path.with_name("IMG-" + base)
    if not img.exists():
        cands = sorted(led_path.parent.glob(f"IMG-*{base}"))
        if not cands:
            raise InputError(f"no image file IMG-{base} beside the leader file", led_path)
        img = cands[0]
    lead = read_leader(led_path)
    desc = read_image_descriptor(img)
    summary = read_summary(summary_path) if summary_path else {}
    product_id = summary.get("Pds_ProductID", base.split("-")[-1])
    letter = view_letter(product_id) or view_letter(base)
    if letter is None:
        raise InputError("cannot tell the view (N, F or B) from the product id "
                         f"{product_id!r} or the file name", led_path)
    return CeosView(letter, img, desc["pixels"], desc["lines"], desc["bits"], lead["crs"],
                    f4_to_map_to_image(lead["f4"], lead["south"]), tuple(lead["f4"]),
                    lead["pixel_size_m"], lead["line_spacing_m"], lead["altitude_m"],
                    lead["heading"], lead["centre_en"], lead["state_vectors"], summary,
                    summary.get("Scs_SceneID", base.split("-")[0]), product_id)
