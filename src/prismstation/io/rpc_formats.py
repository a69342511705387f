"""Parsers of the RPC side files users have: OSSIM ``.geom``, DigitalGlobe ``.RPB``,
``_RPC.TXT``, Pléiades / SPOT DIMAP ``RPC_*.XML`` and JAXA's fixed-width ``RPC-*.txt``.

Each returns a :class:`prismstation.core.rpc.Rpc` in its convention (RPC00B, 0-based image
offsets with the first pixel's centre at 0, as GDAL reads them) or raises
:class:`~prismstation.errors.InputError` naming the file, the line and the problem (a missing
key, a wrong number of coefficients, a value that is not a number, a zero scale).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from prismstation.core.rpc import Rpc
from prismstation.errors import InputError, ModelError

#: the ten scalars under the names every format maps to
SCALARS = ("line_off", "samp_off", "lat_off", "lon_off", "h_off",
           "line_scale", "samp_scale", "lat_scale", "lon_scale", "h_scale")
POLYS = ("line_num", "line_den", "samp_num", "samp_den")


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

    def build(self, fmt: str, names: dict[str, str], coeff_names: dict[str, str],
              index_base: int = 1) -> Rpc:
        """Check and convert: ``names`` maps our scalar name to the file's key, ``coeff_names``
        our polynomial name to the file's key (messages quote the file's own names)."""
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
        try:
            return Rpc(**vals, **polys, source=f"{Path(self.path).name} ({fmt})")
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
    fmt = kv.get("polynomial_format", ("B", None))
    if fmt[0].upper() != "B":
        raise InputError(f"OSSIM geom: polynomial_format {fmt[0]!r} (only RPC00B, 'B', is read)",
                         path, fmt[1])
    rpc = v.build("OSSIM geom", _GEOM_NAMES, _GEOM_COEFFS, index_base=0)
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
    """DigitalGlobe ``.RPB``: ``key = value;`` and ``key = ( c1, …, c20 );`` over lines."""
    v = _Values(path)
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
        if key in by_key:
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
    return v.build("RPB", _RPB_NAMES, _RPB_COEFFS)


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
    """Pléiades / SPOT 6-7 DIMAP v2 ``RPC_*.XML``: ``Global_RFM/Inverse_Model`` (ground →
    image) ``LINE_NUM_COEFF_1`` … and ``RFM_Validity`` offsets and scales.

    Pléiades and SPOT 6/7 count image coordinates from 1 (the first pixel's centre at 1);
    their ``LINE_OFF``/``SAMP_OFF`` lose 1 here, as GDAL does. Pléiades Neo (profile
    ``PNEO…``) counts from 0 and is read as is.
    """
    import xml.etree.ElementTree as ET

    text = _read_text(path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InputError(f"DIMAP RPC: not well-formed XML ({exc.msg})", path,
                         exc.position[0] if exc.position else None) from None
    lines = text.splitlines()

    def line_of(tag):
        pat = f"<{tag}>"
        return next((i for i, s in enumerate(lines, 1) if pat in s), None)

    v = _Values(path)
    names = {o: o.upper().replace("LON_", "LONG_").replace("H_", "HEIGHT_") for o in SCALARS}
    for ours, tag in names.items():
        el = root.find(f".//RFM_Validity/{tag}")
        if el is not None:
            v.scalars[ours] = (el.text or "", line_of(tag))
    inv = root.find(".//Inverse_Model")
    for ours in POLYS:
        for el in ([] if inv is None else inv):
            m = re.fullmatch(rf"{ours.upper()}_COEFF_(\d+)", el.tag)
            if m:
                v.polys[ours][int(m[1]) - 1] = (el.text or "", line_of(el.tag))
    coeffs = {p: p.upper() + "_COEFF" for p in POLYS}
    rpc = v.build("DIMAP RPC", names, coeffs)
    profile = (root.findtext(".//METADATA_PROFILE") or "").strip().upper()
    return rpc if profile.startswith("PNEO") else rpc.shifted(dx=-1.0, dy=-1.0)


# ---------------------------------------------------------------------- JAXA RPC-*.txt
#: field widths of JAXA's one-line layout (GDAL's ALOS metadata reader uses the same)
_ALOS_WIDTHS = (6, 5, 8, 9, 5, 6, 5, 8, 9, 5)
_ALOS_NAMES = {o: o.upper().replace("LON_", "LONG_").replace("H_", "HEIGHT_") for o in SCALARS}
_ALOS_COEFF_WIDTH = 12


def read_alos_txt(path) -> Rpc:
    """JAXA ``RPC-<id>.txt``: one line of fixed-width fields — LINE_OFF (6 characters),
    SAMP_OFF (5), LAT_OFF (8), LONG_OFF (9), HEIGHT_OFF (5), LINE_SCALE (6), SAMP_SCALE (5),
    LAT_SCALE (8), LONG_SCALE (9), HEIGHT_SCALE (5), then 4 × 20 coefficients of 12 characters
    (line numerator, line denominator, sample numerator, sample denominator)."""
    text = _read_text(path)
    first = text.splitlines()[0] if text.strip() else ""
    need = sum(_ALOS_WIDTHS) + 80 * _ALOS_COEFF_WIDTH
    if len(first.rstrip("\r\n")) < need:
        raise InputError(f"JAXA RPC: the line has {len(first)} characters, the fixed-width "
                         f"layout needs {need}", path, 1)
    v = _Values(path)
    pos = 0
    for ours, w in zip(SCALARS, _ALOS_WIDTHS):
        v.scalars[ours] = (first[pos:pos + w], 1)
        pos += w
    for ours in POLYS:
        for i in range(20):
            v.polys[ours][i] = (first[pos:pos + _ALOS_COEFF_WIDTH], 1)
            pos += _ALOS_COEFF_WIDTH
    return v.build("JAXA RPC", _ALOS_NAMES, {p: p.upper() + "_COEFF" for p in POLYS})
