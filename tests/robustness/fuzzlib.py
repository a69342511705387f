"""Shared parts of the fuzz suite: valid documents, mutation strategies, the reader contract.

The contract every reader must keep for any input: it either returns, or raises a
:class:`prismstation.errors.PrismError` whose message names the file and — for a line-based
text file whose problem lies in a line — that line (a real line of the file). Any other
exception is a bug in the reader.

Example counts scale with ``PRISMSTATION_FUZZ`` (default 1; e.g. ``PRISMSTATION_FUZZ=20`` for a
long run, which also draws fresh random cases each run instead of the fixed derandomised ones).
"""
from __future__ import annotations

import json
import os
import re
import traceback
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, event, settings
from hypothesis import strategies as st

from prismstation.errors import InputError, PrismError
from prismstation.io import pointfiles as pfm
from prismstation.io.points import ground_points_csv, measurements_csv
from prismstation.model.points import GroundPoint, Measurement
from prismstation.sim.model_triplet import make_points, make_scene

SCALE = max(1, int(os.environ.get("PRISMSTATION_FUZZ", "1") or 1))


def fuzz_settings(n: int):
    """Hypothesis settings for ``n`` examples in the default run (× ``PRISMSTATION_FUZZ``).

    The default run is derandomised (the same cases every time, so CI is reproducible);
    a scaled run draws new cases.
    """
    return settings(max_examples=n * SCALE, deadline=None, derandomize=SCALE == 1,
                    database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.function_scoped_fixture,
                                           HealthCheck.filter_too_much])


# ----------------------------------------------------------------------------- valid documents
def scene_doc(heading=192.0, path_oriented=True) -> dict:
    """A valid scene.json document (views placed by ``map_to_image``, no image files)."""
    sc = make_scene(heading, path_oriented)
    views = {name: {"image": f"{name}.tif", "pixel_size_m": v.pixel_size_m,
                    "along_track_angle_deg": v.along_track_angle_deg,
                    "map_to_image": v.map_to_image.coeffs()}
             for name, v in sc.views.items()}
    return {"format": "prismstation-scene/1", "crs": sc.crs,
            "satellite_altitude_m": sc.satellite_altitude_m,
            "ground_track": sc.track.points.tolist(), "views": views, "geoid_undulation_m": 55.2}


def synth_points(n_gcp=4, n_icp=3, n_tie=2, seed=3):
    """Ground points and measurements of a synthetic triplet (some ortho heights and sigmas)."""
    sc = make_scene()
    obs = make_points(sc, n_gcp=n_gcp, n_icp=n_icp + n_tie, seed=seed)
    points, meas = [], []
    for i, p in enumerate(obs):
        if i < n_gcp + n_icp:
            E, N, h = p.ground
            points.append(GroundPoint(p.id, E, N, h, "orthometric" if i % 3 == 0 else "ellipsoidal",
                                      p.kind, 0.5 if i % 2 else None, 1.0 if i % 2 else None))
        for v, (x, y) in p.image.items():
            meas.append(Measurement(p.id, v, x, y, 0.7 if i % 4 == 1 else None))
    return points, meas


def points_csv_text() -> str:
    return ground_points_csv(synth_points()[0])


def measurements_csv_text() -> str:
    return measurements_csv(synth_points()[1])


def point_file(fmt: str) -> pfm.PointFile:
    """A valid PointFile for ``fmt`` (QGIS: one view; ASP: geographic; CSV: no measurements)."""
    points, meas = synth_points()
    pf = pfm.PointFile(tuple(points), tuple(meas), "EPSG:32629", fmt)
    if fmt == "qgis":
        pf = pfm.PointFile(pf.points, tuple(m for m in meas if m.view == "N"), pf.crs, fmt)
    elif fmt == "asp":
        pf = pfm.convert_point_file(pf, "EPSG:4326")
    elif fmt == "csv":
        pf = pfm.PointFile(pf.points, (), None, fmt)
    return pf


def point_file_text(fmt: str) -> str:
    formatters = {"qgis": pfm.format_qgis_points, "odm": pfm.format_odm_gcp,
                  "asp": pfm.format_asp_gcp, "csv": pfm.format_ground_csv}
    return formatters[fmt](point_file(fmt))


# ----------------------------------------------------------------------------- mutations
NASTY = ["", " ", "nan", "NaN", "inf", "-inf", "Infinity", "1e309", "-1e309", "-0", "0", "1e-320",
         "abc", "１２", "٣", "1_000", "0x10", "1e", "--1", ".", "+", '"', "'", '""', ",", ";", "\t",
         "#", "# comment", "GCP", "ICP", "TIE", "gcp", "ellipsoidal", "orthometric", "N", "F", "B",
         "X", "EPSG:4326", "EPSG:32629", "EPSG:99999", "+proj=longlat", "WGS84 UTM 61N",
         "WGS84 UTM 0S", "WGS84 UTM 33S", "9" * 400, "\x00", "é", "∞", "\u2028", "\x85", "\r",
         "mapX", "id", "E", "H", "view", "sigma_px", "-1", "1e300", "-5", "1.5e-7", "x" * 300,
         "a\x00b.tif", "/", ".."]

token = st.one_of(st.sampled_from(NASTY), st.text(max_size=8),
                  st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.integers(-10**30, 10**30).map(str))

_SPLIT = re.compile(r"([,;\s]+)")
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def _line_op(draw, lines: list[str]) -> list[str]:
    op = draw(st.sampled_from(["delete", "duplicate", "swap", "field", "field", "field", "drop_field",
                               "add_field", "number", "number", "insert", "truncate_line", "case"]))
    if not lines:
        return [draw(token)]
    # a uniform line index (integers() would favour the header, where most edits stop the read)
    rnd = draw(st.randoms(use_true_random=False))
    i = rnd.randrange(len(lines))
    ln = lines[i]
    if op == "delete":
        return lines[:i] + lines[i + 1:]
    if op == "duplicate":
        return lines[:i + 1] + [ln] + lines[i + 1:]
    if op == "swap":
        j = rnd.randrange(len(lines))
        lines = list(lines)
        lines[i], lines[j] = lines[j], lines[i]
        return lines
    if op in ("field", "drop_field", "add_field"):
        parts = _SPLIT.split(ln)  # fields at even indices, separators at odd ones
        k = 2 * rnd.randrange(len(parts) // 2 + 1)
        if op == "field":
            parts[k] = draw(token)
        elif op == "drop_field":
            parts = parts[:max(k - 1, 0)] + parts[k + 1:]
        else:
            parts = parts[:k + 1] + [draw(st.sampled_from([",", " ", ";", "\t", ", "])), draw(token)] + parts[k + 1:]
        return lines[:i] + ["".join(parts)] + lines[i + 1:]
    if op == "number":
        nums = list(_NUMBER.finditer(ln))
        if not nums:
            return lines
        m = nums[rnd.randrange(len(nums))]
        new = draw(st.one_of(token, st.floats().map(repr), st.sampled_from(["-" + m.group(), m.group() * 2])))
        return lines[:i] + [ln[:m.start()] + new + ln[m.end():]] + lines[i + 1:]
    if op == "insert":
        return lines[:i] + [draw(st.one_of(token, st.text(max_size=40)))] + lines[i:]
    if op == "truncate_line":
        k = draw(st.integers(0, len(ln)))
        return lines[:i] + [ln[:k]] + lines[i + 1:]
    return lines[:i] + [draw(st.sampled_from([str.upper, str.lower, str.swapcase]))(ln)] + lines[i + 1:]


@st.composite
def mutated_text(draw, base: str) -> bytes:
    """``base`` with 1–4 line / field / number edits, maybe truncated, re-encoded or bit-flipped."""
    lines = base.splitlines()
    for _ in range(draw(st.sampled_from([1, 1, 1, 2, 2, 3, 4]))):
        lines = _line_op(draw, lines)
    text = draw(st.sampled_from(["\n", "\r\n", "\r"])).join(lines) + draw(st.sampled_from(["\n", ""]))
    if draw(st.integers(0, 9)) == 0:
        text = text[:draw(st.integers(0, len(text)))]
    return _bytes(draw, text)


def _bytes(draw, text: str) -> bytes:
    enc = draw(st.sampled_from(["utf-8"] * 12 + ["utf-8-sig", "latin-1", "utf-16", "cp1252"]))
    data = text.encode(enc, errors="replace")
    if data and draw(st.integers(0, 11)) == 0:
        k = draw(st.integers(0, len(data) - 1))
        data = data[:k] + bytes([data[k] ^ (1 << draw(st.integers(0, 7)))]) + data[k + 1:]
    return data


json_value = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20),
              st.sampled_from([10**400, -10**400, 2**63, 2**64, 0, -1]),
              st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(NASTY), st.text(max_size=10)),
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.sampled_from(["N", "F", "B", "id", "x", "image", "kind",
                                                             "value", "path"]) | st.text(max_size=5),
                                            inner, max_size=4)),
    max_leaves=8)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


@st.composite
def mutated_json(draw, base: dict) -> bytes:
    """``base`` with 1–3 edits at random paths (replace, delete, add, re-type), dumped, and
    sometimes further edited as text."""
    doc = json.loads(json.dumps(base))
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(doc))
        path = draw(st.sampled_from(paths))
        op = draw(st.sampled_from(["replace", "replace", "delete", "add", "stringify", "wrap"]))
        if not path:
            doc = draw(json_value) if op == "replace" and draw(st.integers(0, 4)) == 0 else doc
            continue
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        key = path[-1]
        if op == "replace":
            parent[key] = draw(json_value)
        elif op == "delete":
            del parent[key]
        elif op == "add" and isinstance(parent, dict):
            parent[draw(st.text(max_size=6))] = draw(json_value)
        elif op == "add":
            parent.insert(key, draw(json_value))
        elif op == "stringify":
            parent[key] = json.dumps(parent[key]) if not isinstance(parent[key], str) else 7
        else:
            parent[key] = [parent[key]]
    text = json.dumps(doc, indent=draw(st.sampled_from([None, 1, 2])), ensure_ascii=draw(st.booleans()))
    if draw(st.integers(0, 4)) == 0:
        return draw(mutated_text(text))
    return _bytes(draw, text)


def any_input(base_text: str | None = None, base_json: dict | None = None):
    """Random bytes, random text, or mutations of the valid document given."""
    options = [st.binary(max_size=600), st.text(max_size=300).map(lambda s: s.encode("utf-8", "surrogatepass"))]
    if base_text is not None:
        options += [mutated_text(base_text)] * 6
    if base_json is not None:
        options += [mutated_json(base_json)] * 6
    return st.one_of(options)


# ----------------------------------------------------------------------------- the contract
_WHOLE_FILE = re.compile(r"empty|no header|no points|UTF-8|not a text file|cannot read|file not found|"
                         r"unknown point-file format|not in the scene|already exists", re.I)


def check_reader(read, path: Path, data: bytes, *, lined: bool):
    """Write ``data`` to ``path``, call ``read(path)`` and check the reader contract.

    Returns the result, or the PrismError raised. ``lined``: the format is line-based text,
    so an error about a line must name it.
    """
    path.write_bytes(data)
    try:
        out = read(path)
    except PrismError as exc:
        check_error(exc, path, data, lined=lined)
        event(f"{type(exc).__name__}: {getattr(exc, 'problem', str(exc))[:28]}")
        return exc
    except Exception:  # noqa: BLE001 - the point of the test
        raise AssertionError(f"reader raised a non-PrismError for {data[:300]!r}:\n"
                             f"{traceback.format_exc()}") from None
    event("read")
    return out


def check_error(exc: PrismError, path: Path, data: bytes, *, lined: bool) -> None:
    msg = str(exc)
    assert msg.strip() and "\n" not in msg.strip(), f"empty or multi-line message {msg!r}"
    assert path.name in msg, f"message does not name the file: {msg!r}"
    if not isinstance(exc, InputError):
        return
    n_lines = len(data.splitlines()) + 1
    try:  # the readers count lines as str.splitlines does (\x1c, \x85, \u2028... end lines too)
        n_lines = max(n_lines, len(data.decode("utf-8-sig").splitlines()) + 1)
    except UnicodeDecodeError:
        pass
    if exc.line is not None:
        assert 1 <= exc.line <= max(n_lines, 1), f"line {exc.line} outside the file ({n_lines}): {msg!r}"
    elif lined:
        assert _WHOLE_FILE.search(exc.problem), f"a line problem without its line: {msg!r}"


def json_error_has_line(exc, data: bytes) -> None:
    """Invalid JSON text must be reported with its line."""
    try:
        json.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        return
    except ValueError:
        assert isinstance(exc, InputError) and exc.line is not None, f"JSON syntax error without line: {exc}"


def finite(*values) -> bool:
    return bool(np.all(np.isfinite(np.asarray(values, float))))
