"""JSON files with errors that name the file and the line.

The one JSON writer: :func:`plain` makes a value JSON-safe (numpy → Python, tuples → lists,
NaN and ±inf → ``null``), :func:`dumps` serialises it (never NaN: ``allow_nan=False`` after
:func:`plain`), :func:`write_json` writes it atomically (:mod:`prismstation.io.atomic`).
"""
from __future__ import annotations

import json
import math
import re

import numpy as np

from prismstation.errors import InputError
from prismstation.io.atomic import write_atomic
from prismstation.io.inputs import local_file


def plain(v):
    """``v`` JSON-safe: numpy scalars and arrays → Python, tuples → lists, non-finite floats →
    ``None``, dict keys → str, objects with ``to_dict()`` → that dict."""
    t = type(v)  # the common leaves first (a project: thousands of them, journaled at every edit)
    if t is str or t is int or t is bool or v is None:
        return v
    if t is float:
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {str(k): plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return plain(v.tolist())
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (np.floating, float)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    if hasattr(v, "to_dict"):
        return plain(v.to_dict())
    return v


def number(v) -> float:
    """A JSON number as a float, NaN where :func:`plain` wrote None (a value not there)."""
    return math.nan if v is None else float(v)


def dumps(obj, indent: int | None = None) -> str:
    """JSON text of ``obj`` (through :func:`plain`: no NaN, no numpy), UTF-8 characters kept."""
    return json.dumps(plain(obj), indent=indent, ensure_ascii=False, allow_nan=False)


def write_json(path, obj, indent: int = 2, keep_backup: bool = False) -> None:
    """Write ``obj`` as JSON atomically (:func:`dumps`, :func:`prismstation.io.atomic.write_atomic`);
    a failure is a :class:`~prismstation.errors.WriteError` naming ``path``."""
    write_atomic(path, dumps(obj, indent) + "\n", keep_backup=keep_backup)


def read_json(path) -> tuple[dict, str]:
    """Parse a JSON object; returns ``(data, text)``. Bad JSON → InputError with its line."""
    path = local_file(path)  # not a FIFO, a device, a folder, a link loop (it would hang or fail)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read: {exc}", path) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", path, exc.lineno) from None
    except RecursionError:  # [[[[… a hundred thousand deep
        raise InputError("not a usable JSON document: nested too deep", path) from None
    if not isinstance(data, dict):
        raise InputError("expected a JSON object at the top level", path, 1)
    return data, text


def line_of(text: str, key: str) -> int | None:
    """1-based line of the first ``"key":`` in ``text`` (best effort, for messages)."""
    m = re.search(r'"%s"\s*:' % re.escape(key), text)
    return None if m is None else text.count("\n", 0, m.start()) + 1
