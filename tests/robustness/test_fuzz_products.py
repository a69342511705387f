"""Fuzzing the JAXA product readers (``io.ceos``, ``io.products``): a CEOS triplet built byte by
byte (tests/io/formats/fixtures/ceos_builder.py) with one file spoiled — numeric fields of the
leader's map-projection and platform-position records, the image descriptor, record lengths,
the F4 doubles, ``summary.txt`` lines — must read or raise a PrismError naming that file."""
from __future__ import annotations

import shutil
import struct
import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from prismstation.errors import PrismError
from prismstation.io.products import scene_dict_from_product
from tests.io.formats.fixtures import ceos_builder as cb
from tests.robustness import fuzzlib as fz

# (record number, offset in the record, size) of the text fields the readers parse
LEADER_FIELDS = ([(3, o, s) for o, s in ((92, 4), (96, 12), (140, 16), (156, 16), (540, 16),
                                         (556, 16), (668, 16), (700, 16))]
                 + [(5, o, s) for o, s in ((140, 4), (144, 4), (148, 4), (152, 4), (160, 22), (182, 22))]
                 + [(5, 386 + 22 * j, 22) for j in range(12)])
F4 = [(3, 1916 + 8 * j, 8) for j in range(6)]
IMG_FIELDS = [(1, o, s) for o, s in ((180, 6), (186, 6), (216, 4), (236, 8), (248, 8), (280, 4), (284, 8))]
NUMBERS = ["", "0", "1", "-1", "2", "60", "61", "8", "16", "nan", "inf", "1e308", "9" * 22, "-9" * 11,
           "1D3", "abc", "0.0000001", "-0", "1e-300", "4680", "999999", "12", "-12"]


def _record_starts(data: bytes) -> list[int]:
    starts, pos = [], 0
    while pos + 12 <= len(data):
        starts.append(pos)
        pos += struct.unpack(">I", data[pos + 8:pos + 12])[0]
    return starts


@st.composite
def spoiled(draw, data: bytes, fields, doubles=()):
    """``data`` with 1–3 of: a text field rewritten, an F4 double replaced, a record length
    changed, a byte flipped, or the file truncated."""
    b = bytearray(data)
    starts = _record_starts(data)
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["field"] * 5 + ["double", "length", "flip", "truncate"]))
        if op == "field":
            rec, off, size = draw(st.sampled_from(fields))
            text = draw(st.one_of(st.sampled_from(NUMBERS), st.floats().map(repr),
                                  st.text(alphabet="0123456789.-+eED naif", max_size=size)))
            pos = starts[rec - 1] + off if rec - 1 < len(starts) else None
            if pos is not None and pos + size <= len(b):
                b[pos:pos + size] = text.encode("ascii")[:size].rjust(size)
        elif op == "double" and doubles:
            rec, off, _ = draw(st.sampled_from(doubles))
            pos = starts[rec - 1] + off if rec - 1 < len(starts) else None
            if pos is not None and pos + 8 <= len(b):
                b[pos:pos + 8] = struct.pack(">d", draw(st.floats(allow_nan=True, allow_infinity=True)))
        elif op == "length" and starts:
            s = draw(st.sampled_from(starts))
            b[s + 8:s + 12] = struct.pack(">I", draw(st.integers(0, 2**32 - 1) | st.integers(0, 6000)))
        elif op == "flip" and b:
            rnd = draw(st.randoms(use_true_random=False))
            k = rnd.randrange(len(b))
            b[k] ^= 1 << rnd.randrange(8)
        elif op == "truncate":
            del b[draw(st.integers(0, len(b))):]
    return bytes(b)


@pytest.fixture(scope="module")
def product():
    root = Path(tempfile.mkdtemp(prefix="prism_ceos_fuzz_"))
    cb.build_triplet(root / "p")
    scene = scene_dict_from_product(root / "p")  # the valid product reads
    assert set(scene["views"]) == {"N", "F", "B"}
    folder = next((root / "p").glob("*_UF"))
    files = {kind: next(folder.glob(pat)) for kind, pat in
             (("led", "LED-*"), ("img", "IMG-*"), ("summary", "summary.txt"))}
    yield root / "p", files, {k: f.read_bytes() for k, f in files.items()}
    shutil.rmtree(root, ignore_errors=True)


def _check(product_dir, bad: Path, data: bytes, original: bytes):
    bad.write_bytes(data)
    try:
        scene_dict_from_product(product_dir)
    except PrismError as exc:
        msg = str(exc)
        assert msg.strip() and "\n" not in msg.strip(), msg
        assert bad.name in msg, f"the message does not name {bad.name}: {msg}"
    except Exception as exc:  # noqa: BLE001
        raise AssertionError(f"{type(exc).__name__}: {exc}") from exc
    finally:
        bad.write_bytes(original)


def test_fuzz_leader(product):
    root, files, orig = product

    @fz.fuzz_settings(150)
    @given(data=spoiled(orig["led"], LEADER_FIELDS, F4))
    def run(data):
        _check(root, files["led"], data, orig["led"])

    run()


def test_fuzz_image_descriptor(product):
    root, files, orig = product

    @fz.fuzz_settings(80)
    @given(data=spoiled(orig["img"], IMG_FIELDS))
    def run(data):
        _check(root, files["img"], data, orig["img"])

    run()


def test_fuzz_summary(product):
    root, files, orig = product

    @fz.fuzz_settings(80)
    @given(data=fz.mutated_text(orig["summary"].decode("latin-1")))
    def run(data):
        _check(root, files["summary"], data, orig["summary"])

    run()
