"""Parsers of the RPC files users have: OSSIM ``.geom``, DigitalGlobe ``.RPB``,
``_RPC.TXT``, Pléiades / SPOT / Pléiades Neo DIMAP ``RPC_*.XML``, JAXA's fixed-width
``RPC-*.txt`` and the NITF ``RPC00A`` tagged record.

Each returns a :class:`prismstation.core.models.rpc.Rpc` in its convention (RPC00B, 0-based image
offsets with the first pixel's centre at 0, as GDAL reads them) or raises
:class:`~prismstation.errors.InputError` naming the file, the line and the problem (a missing
key, a wrong number of coefficients, a value that is not a number, a zero scale, a polynomial
order that is neither RPC00A nor RPC00B).

**RPC00A** orders the 20 terms differently from RPC00B (the NITF tagged record of that name,
a ``.RPB`` with ``specId = "RPC00A"``, a DIMAP file whose ``RESOURCE_ID`` is ``RPC00A``, an
OSSIM ``.geom`` with ``polynomial_format: A``): 1, L, P, H, LP, LH, PH, **LPH, L², P², H²**,
L³, **L²P, L²H, LP²**, P³, **P²H, LH², PH²**, H³. Read as RPC00B such coefficients put a
point tens of pixels off; they are reordered here (:func:`rpc00a_to_b`).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from prismstation.core.models.rpc import Rpc
from prismstation.errors import InputError, ModelError

#: the ten scalars under the names every format maps to
SCALARS = ("line_off", "samp_off", "lat_off", "lon_off", "h_off",
           "line_scale", "samp_scale", "lat_scale", "lon_scale", "h_scale")
POLYS = ("line_num", "line_den", "samp_num", "samp_den")
#: the RPC00B position of each RPC00A term, in RPC00A's order (module docstring)
RPC00A_TO_B = (0, 1, 2, 3, 4, 5, 6, 10, 7, 8, 9, 11, 14, 17, 12, 15, 18, 13, 16, 19)
#: the polynomial orders these readers know, by the names the formats give them
ORDERS = ("RPC00A", "RPC00B")


def rpc00a_to_b(coeffs) -> np.ndarray:
    """``(20,)`` RPC00A-ordered coefficients in RPC00B's order."""
    out = np.empty(20)
    out[list(RPC00A_TO_B)] = np.asarray(coeffs, float)
    return out


class _Values:
    """Values read from one file, each with the line it came from (1-based or None)."""

    def __init__(self, path):
        self.path = str(path)
        self.scalars: dict[str, tuple[str, int | None]] = {}
        self.polys: dict[str, dict[int, tuple[str, int | None]]] = {p: {} for p in POLYS}

    def number(self, text: str, what: str, line: int | None) -> float:
        try:
            v = float(text.strip())
        except ValueError:
            raise InputError(f"{what}: {text.strip()!r} is not a number", self.path, line) from None
        if not math.isfinite(v):
            raise InputError(f"{what}: {text.strip()!r} is not a finite number", self.path, line)
        return v

    def order(self, value: str, what: str, line: int | None, fmt: str) -> str:
        """The polynomial order a file states (``RPC00A`` or ``RPC00B``), else refused."""
        v = value.strip().strip('"').strip("'").strip().upper()
        if v not in ORDERS:
            raise InputError(f"{fmt}: {what} {v!r} is not a polynomial order this reader "
                             f"knows ({' or '.join(ORDERS)})", self.path, line)
        return v

    def build(self, fmt: str, names: dict[str, str], coeff_names: dict[str, str],
              index_base: int = 1, order: str = "RPC00B") -> Rpc:
        """Check and convert: ``names`` maps our scalar name to the file's key, ``coeff_names``
        our polynomial name to the file's key (messages quote the file's own names);
        ``order`` the file's term order (RPC00A is reordered to RPC00B)."""
        vals = {}
        for ours in SCALARS:
            key = names[ours]
            if ours not in self.scalars:
                raise InputError(f"{fmt}: the key {key} is missing", self.path)
            text, line = self.scalars[ours]
            vals[ours] = self.number(text, key, line)
            if ours.endswith("_scale") and vals[ours] == 0:
                raise InputError(f"{fmt}: {key} is zero (a scale must not be)", self.path, line)
        polys = {}
        for ours in POLYS:
            got = self.polys[ours]
            key = coeff_names[ours]
            if len(got) != 20 or sorted(got) != list(range(20)):
                missing = sorted(set(range(20)) - set(got))
                extra = sorted(set(got) - set(range(20)))
                detail = (f"missing {key} {', '.join(str(i + index_base) for i in missing)}"
                          if missing else f"unexpected index {extra[0] + index_base}")
                line = next(iter(got.values()))[1] if got else None
                raise InputError(f"{fmt}: {key} needs 20 coefficients, found {len(got)} "
                                 f"({detail})", self.path, line)
            polys[ours] = np.array([self.number(got[i][0], f"{key} {i + index_base}", got[i][1])
                                    for i in range(20)])
            if ours.endswith("_den") and not np.any(polys[ours]):
                raise InputError(f"{fmt}: {key} is all zeros (a denominator must not be)",
                                 self.path, got[0][1])
            if order == "RPC00A":
                polys[ours] = rpc00a_to_b(polys[ours])
        how = fmt if order == "RPC00B" else f"{fmt}, RPC00A reordered to RPC00B"
        try:
            return Rpc(**vals, **polys, source=f"{Path(self.path).name} ({how})")
        except ModelError as exc:  # pragma: no cover - every check above comes first
            raise InputError(f"{fmt}: {exc}", self.path) from None


def _read_text(path) -> str:
    try:
        return Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror or exc})", path) from None


# ---------------------------------------------------------------------- OSSIM .geom
_GEOM_NAMES = {"line_off": "line_off", "samp_off": "samp_off", "lat_off": "lat_off",
               "lon_off": "long_off", "h_off": "height_off", "line_scale": "line_scale",
               "samp_scale": "samp_scale", "lat_scale": "lat_scale", "lon_scale": "long_scale",
               "h_scale": "height_scale"}
_GEOM_COEFFS = {p: p + "_coeff" for p in POLYS}


def read_geom(path) -> Rpc:
    """OSSIM keyword list (``key:  value`` lines; coefficients ``line_num_coeff_00`` … ``_19``).

    ``polynomial_format: A`` is RPC00A (reordered), ``B`` (or none) RPC00B.
    OSSIM's image coordinates are 0-based with the first pixel's centre at 0, as GDAL's. Its
    adjustable image-space parameters (the current ``adjustment_N``) move the image point by
    ``center + sigma × parameter``: ``intrack_offset`` is added to the line, ``crtrack_offset``
    to the sample and both are folded into the offsets; a non-zero ``intrack_scale``,
    ``crtrack_scale`` or ``map_rotation`` is refused (not an RPC00B any more).
    """
    v = _Values(path)
    kv: dict[str, tuple[str, int]] = {}
    for n, raw in enumerate(_read_text(path).splitlines(), 1):
        if not raw.strip() or raw.lstrip().startswith("//"):
            continue
        key, sep, value = raw.partition(":")
        if not sep:
            raise InputError(f"OSSIM geom: expected 'key: value', got {raw.strip()[:60]!r}", path, n)
        kv[key.strip()] = (value.strip(), n)
    inverse = {k: ours for ours, k in _GEOM_NAMES.items()}
    for key, (value, n) in kv.items():
        if key in inverse:
            v.scalars[inverse[key]] = (value, n)
            continue
        m = re.fullmatch(r"(line|samp)_(num|den)_coeff_(\d+)", key)
        if m:
            v.polys[f"{m[1]}_{m[2]}"][int(m[3])] = (value, n)
    fmt, fmt_line = kv.get("polynomial_format", ("B", None))
    order = v.order(f"RPC00{fmt}" if fmt.strip().upper() in ("A", "B") else fmt,
                    "polynomial_format", fmt_line, "OSSIM geom")
    rpc = v.build("OSSIM geom", _GEOM_NAMES, _GEOM_COEFFS, index_base=0, order=order)
    shift = {"intrack_offset": 0.0, "crtrack_offset": 0.0}
    current = kv.get("current_adjustment", ("0", None))[0]
    prefix = f"adjustment_{current}.adj_param_"
    for key, (desc, n) in kv.items():
        if not (key.startswith(prefix) and key.endswith(".description")):
            continue
        base = key[: -len(".description")]

        def num(field, default):
            k = base + field
            return v.number(kv[k][0], k, kv[k][1]) if k in kv else default

        value = num(".center", 0.0) + num(".parameter", 0.0) * num(".sigma", 1.0)
        if desc in shift:
            shift[desc] = value
        elif value != 0:
            raise InputError(f"OSSIM geom: adjustable parameter {desc} = {value:g} is not "
                             "supported (only intrack_offset and crtrack_offset)", path, n)
    return rpc.shifted(dx=shift["crtrack_offset"], dy=shift["intrack_offset"])


# ---------------------------------------------------------------------- DigitalGlobe .RPB
_RPB_NAMES = {"line_off": "lineOffset", "samp_off": "sampOffset", "lat_off": "latOffset",
              "lon_off": "longOffset", "h_off": "heightOffset", "line_scale": "lineScale",
              "samp_scale": "sampScale", "lat_scale": "latScale", "lon_scale": "longScale",
              "h_scale": "heightScale"}
_RPB_COEFFS = {"line_num": "lineNumCoef", "line_den": "lineDenCoef",
               "samp_num": "sampNumCoef", "samp_den": "sampDenCoef"}


def read_rpb(path) -> Rpc:
    """DigitalGlobe ``.RPB``: ``key = value;`` and ``key = ( c1, …, c20 );`` over lines;
    ``specId = "RPC00A"`` is RPC00A (reordered), ``"RPC00B"`` (or none) RPC00B."""
    v = _Values(path)
    order = "RPC00B"
    by_key = {k.lower(): o for o, k in _RPB_NAMES.items()}
    coef_key = {k.lower(): o for o, k in _RPB_COEFFS.items()}
    open_list, items = None, []
    for n, raw in enumerate(_read_text(path).splitlines(), 1):
        line = raw.strip()
        if open_list is not None:
            items += [(t, n) for t in line.replace(")", "").replace(";", "").split(",") if t.strip()]
            if ")" in line:
                v.polys[open_list] = {i: t for i, t in enumerate(items)}
                open_list = None
            continue
        key, sep, value = line.partition("=")
        key = key.strip().lower()
        if not sep:
            continue
        value = value.strip().rstrip(";").strip()
        if key == "specid":
            order = v.order(value, "specId", n, "RPB")
        elif key in by_key:
            v.scalars[by_key[key]] = (value, n)
        elif key in coef_key:
            open_list, items = coef_key[key], []
            body = value.lstrip("(")
            items += [(t, n) for t in body.replace(")", "").split(",") if t.strip()]
            if ")" in value:
                v.polys[open_list] = {i: t for i, t in enumerate(items)}
                open_list = None
    if open_list is not None:
        raise InputError(f"RPB: the list {_RPB_COEFFS[open_list]} is not closed", path)
    return v.build("RPB", _RPB_NAMES, _RPB_COEFFS, order=order)


# ---------------------------------------------------------------------- _RPC.TXT
_TXT_NAMES = {o: o.upper().replace("LON_", "LONG_").replace("H_", "HEIGHT_") for o in SCALARS}
_TXT_COEFFS = {p: p.upper() + "_COEFF" for p in POLYS}


def read_rpc_txt(path) -> Rpc:
    """``_RPC.TXT`` (GDAL's and many vendors' text form): ``LINE_OFF: +003456.00 pixels``,
    ``LINE_NUM_COEFF_1: …`` to ``_20``; units after the number are ignored."""
    v = _Values(path)
    inverse = {k: o for o, k in _TXT_NAMES.items()}
    for n, raw in enumerate(_read_text(path).splitlines(), 1):
        key, sep, value = raw.partition(":")
        if not sep:
            continue
        key = key.strip().upper()
        token = (value.split() or [""])[0]
        if key in inverse:
            v.scalars[inverse[key]] = (token, n)
            continue
        m = re.fullmatch(r"(LINE|SAMP)_(NUM|DEN)_COEFF_(\d+)", key)
        if m:
            v.polys[f"{m[1].lower()}_{m[2].lower()}"][int(m[3]) - 1] = (token, n)
    return v.build("RPC text", _TXT_NAMES, _TXT_COEFFS)


# ---------------------------------------------------------------------- DIMAP RPC_*.XML
def read_dimap_xml(path) -> Rpc:
    """Pléiades / SPOT 6-7 DIMAP v2 and Pléiades Neo DIMAP v3 ``RPC_*.XML``: the ground → image
    model (``Global_RFM/Inverse_Model``; v3 ``GroundtoImage_Values``) ``LINE_NUM_COEFF_1`` …,
    the ``RFM_Validity`` offsets and scales, and ``Resource_Reference/RESOURCE_ID`` the
    polynomial order (``RPC00A`` reordered; ``RPC00B`` or none as is).

    Pléiades and SPOT 6/7 count image coordinates from 1 (the first pixel's centre at 1);
    their ``LINE_OFF``/``SAMP_OFF`` lose 1 here, as GDAL does. Pléiades Neo (profile
    ``PNEO…``) is read as counting from 0, as GDAL 3.10 reads it (whatever its
    ``ImagetoGround_Validity_Domain`` says; CNES's shareloc takes v3 offsets as counted from
    0.5 — half a pixel apart, which no sample at hand settles).
    """
    import xml.etree.ElementTree as ET

    text = _read_text(path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InputError(f"DIMAP RPC: not well-formed XML ({exc.msg})", path,
                         exc.position[0] if exc.position else None) from None
    lines = text.splitlines()

    def line_of(tag, after=0):
        pat = f"<{tag}>"
        return next((i for i, s in enumerate(lines, 1) if i > after and pat in s), None)

    v = _Values(path)
    names = {o: o.upper().replace("LON_", "LONG_").replace("H_", "HEIGHT_") for o in SCALARS}
    for ours, tag in names.items():
        el = root.find(f".//RFM_Validity/{tag}")
        if el is not None:
            v.scalars[ours] = (el.text or "", line_of(tag, line_of("RFM_Validity") or 0))
    block = next(((b, el) for b in ("Inverse_Model", "GroundtoImage_Values")
                  if (el := root.find(f".//{b}")) is not None), None)
    if block is None:
        raise InputError("DIMAP RPC: no ground → image model (Inverse_Model or GroundtoImage_Values)",
                         path)
    after = line_of(block[0]) or 0
    for ours in POLYS:
        for el in block[1]:
            m = re.fullmatch(rf"{ours.upper()}_COEFF_(\d+)", el.tag)
            if m:
                v.polys[ours][int(m[1]) - 1] = (el.text or "", line_of(el.tag, after))
    order = "RPC00B"
    rid = root.find(".//Resource_Reference/RESOURCE_ID")
    if rid is not None:
        order = v.order(rid.text or "", "RESOURCE_ID", line_of("RESOURCE_ID"), "DIMAP RPC")
    coeffs = {p: p.upper() + "_COEFF" for p in POLYS}
    rpc = v.build("DIMAP RPC", names, coeffs, order=order)
    profile = (root.findtext(".//METADATA_PROFILE") or "").strip().upper()
    return rpc if profile.startswith("PNEO") else rpc.shifted(dx=-1.0, dy=-1.0)


# ---------------------------------------------------------------------- fixed width
#: field widths of the NITF RPC00A/RPC00B layout from LINE_OFF on (JAXA's RPC-*.txt is that
#: layout without its first fields; GDAL's ALOS and NITF readers use the same widths)
_FIXED_WIDTHS = (6, 5, 8, 9, 5, 6, 5, 8, 9, 5)
_FIXED_NAMES = {o: o.upper().replace("LON_", "LONG_").replace("H_", "HEIGHT_") for o in SCALARS}
_COEFF_WIDTH = 12
#: SUCCESS (1), ERR_BIAS (7), ERR_RAND (7): what a NITF record holds before LINE_OFF
_NITF_HEAD = 15


def _fixed_width(v: _Values, line: str, line_no: int | None, fmt: str, order: str = "RPC00B") -> Rpc:
    """The ten offsets and scales and 4 × 20 coefficients of ``line`` (from LINE_OFF on)."""
    need = sum(_FIXED_WIDTHS) + 80 * _COEFF_WIDTH
    if len(line.rstrip("\r\n")) < need:
        raise InputError(f"{fmt}: the line has {len(line)} characters, the fixed-width "
                         f"layout needs {need}", v.path, line_no)
    pos = 0
    for ours, w in zip(SCALARS, _FIXED_WIDTHS):
        v.scalars[ours] = (line[pos:pos + w], line_no)
        pos += w
    for ours in POLYS:
        for i in range(20):
            v.polys[ours][i] = (line[pos:pos + _COEFF_WIDTH], line_no)
            pos += _COEFF_WIDTH
    return v.build(fmt, _FIXED_NAMES, {p: p.upper() + "_COEFF" for p in POLYS}, order=order)


def read_alos_txt(path) -> Rpc:
    """JAXA ``RPC-<id>.txt``: one line of fixed-width fields — LINE_OFF (6 characters),
    SAMP_OFF (5), LAT_OFF (8), LONG_OFF (9), HEIGHT_OFF (5), LINE_SCALE (6), SAMP_SCALE (5),
    LAT_SCALE (8), LONG_SCALE (9), HEIGHT_SCALE (5), then 4 × 20 coefficients of 12 characters
    (line numerator, line denominator, sample numerator, sample denominator)."""
    text = _read_text(path)
    return _fixed_width(_Values(path), text.splitlines()[0] if text.strip() else "", 1, "JAXA RPC")


def read_nitf_tre(tag: str, record: str, path) -> Rpc:
    """A NITF ``RPC00A`` or ``RPC00B`` tagged record (``record``: its 1,041 characters, as
    GDAL's ``TRE`` metadata domain holds them): SUCCESS, ERR_BIAS, ERR_RAND, then the layout of
    :func:`read_alos_txt`. ``RPC00A`` is reordered."""
    v = _Values(path)
    order = v.order(tag, "tagged record", None, "NITF")
    return _fixed_width(v, record[_NITF_HEAD:], None, f"NITF {tag}", order=order)
