"""RPC00A-ordered coefficients in every format that can state the order, and Pléiades Neo
DIMAP v3, written here from a real RPC00B and read back.

RPC00A (NITF STDI-0002) and RPC00B order the 20 terms differently; the orders are written
below as monomials (exponents of L, P, H), independently of the reader's table. Each sample is
the triplet's first RPC with its coefficients put in RPC00A order and the format's RPC00A
marker (NITF tagged record ``RPC00A``, ``.RPB`` ``specId``, DIMAP ``RESOURCE_ID``, OSSIM
``polynomial_format``); read back, it must project every ground point where the RPC00B
original does (1e-9 px). GDAL is checked where it reads the format: it agrees on RPC00B and on
the Pléiades Neo layout, and does not on RPC00A (it reads ``.RPB`` and DIMAP RPC00A as RPC00B,
and moves the NITF record's LPH, L², P², H² terms to the wrong places).
"""
from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
import rasterio

from prismstation.errors import InputError
from prismstation.io.rpc import read_rpc, read_rpc_file, rpc_from_rasterio
from tests.io.test_rpc import agreement, gdal_transformer, plain_tif, write_rpb

# (L, P, H) exponents of each term, in each standard's order
RPC00B_TERMS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1), (2, 0, 0),
                (0, 2, 0), (0, 0, 2), (1, 1, 1), (3, 0, 0), (1, 2, 0), (1, 0, 2), (2, 1, 0), (0, 3, 0),
                (0, 1, 2), (2, 0, 1), (0, 2, 1), (0, 0, 3)]
RPC00A_TERMS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1), (1, 1, 1),
                (2, 0, 0), (0, 2, 0), (0, 0, 2), (3, 0, 0), (2, 1, 0), (2, 0, 1), (1, 2, 0), (0, 3, 0),
                (0, 2, 1), (1, 0, 2), (0, 1, 2), (0, 0, 3)]
POLYS = ("line_num", "line_den", "samp_num", "samp_den")


def as_rpc00a(rpc):
    """The same model with its coefficients in RPC00A order (what an RPC00A file holds)."""
    where = [RPC00B_TERMS.index(t) for t in RPC00A_TERMS]
    return replace(rpc, **{p: getattr(rpc, p)[where] for p in POLYS})


def ground_points(rpc, n=300, seed=0):
    rng = np.random.default_rng(seed)
    return (rpc.lon_off + rng.uniform(-1, 1, n) * rpc.lon_scale,
            rpc.lat_off + rng.uniform(-1, 1, n) * rpc.lat_scale,
            rpc.h_off + rng.uniform(-1, 1, n) * rpc.h_scale)


def max_px(a, b):
    """Largest ground → image difference (px) of two models over their ground domain."""
    g = ground_points(a)
    return float(np.max(np.abs(np.subtract(a.project(*g), b.project(*g)))))


@pytest.fixture(scope="module")
def original(shared_data):
    return read_rpc(shared_data / "pleiades_triplet" / "img_01.tif")


# ----------------------------------------------------------------- writers
def write_geom(rpc, path, polynomial_format="B"):
    g = rpc.to_gdal_dict()
    out = ["type:  ossimRpcModel", f"polynomial_format:  {polynomial_format}"]
    out += [f"{k}:  {g[k.upper()]}" for k in ("line_off", "samp_off", "lat_off", "long_off", "height_off",
                                                "line_scale", "samp_scale", "lat_scale", "long_scale",
                                                "height_scale")]
    for p in POLYS:
        out += [f"{p}_coeff_{i:02d}:  {float(c)!r}" for i, c in enumerate(getattr(rpc, p))]
    path.write_text("\n".join(out) + "\n")


def write_dimap(rpc, path, *, resource_id="RPC00B", version=2, first=None):
    """A DIMAP RPC file: v2 (Pléiades: ``Inverse_Model``, offsets counted from 1) or v3
    (Pléiades Neo, GDAL's sample's shape: ``GroundtoImage_Values``, offsets counted from 0;
    with ``first`` an ``ImagetoGround_Validity_Domain`` whose first pixel is ``first``)."""
    origin = 1.0 if version == 2 else 0.0
    g = {k: repr(float(getattr(rpc, a))) for k, a in (
        ("LONG_SCALE", "lon_scale"), ("LONG_OFF", "lon_off"), ("LAT_SCALE", "lat_scale"),
        ("LAT_OFF", "lat_off"), ("HEIGHT_SCALE", "h_scale"), ("HEIGHT_OFF", "h_off"),
        ("SAMP_SCALE", "samp_scale"), ("LINE_SCALE", "line_scale"))}
    g["SAMP_OFF"] = repr(rpc.samp_off + origin)
    g["LINE_OFF"] = repr(rpc.line_off + origin)
    block = "Inverse_Model" if version == 2 else "GroundtoImage_Values"
    profile = "PHR_SENSOR" if version == 2 else "PNEO_SENSOR"
    out = ['<?xml version="1.0" encoding="UTF-8" standalone="yes"?>', "<Dimap_Document>",
           "\t<Metadata_Identification>",
           f'\t\t<METADATA_FORMAT version="{version}.0" profile="{profile}">DIMAP</METADATA_FORMAT>',
           f"\t\t<METADATA_PROFILE>{profile}</METADATA_PROFILE>", "\t</Metadata_Identification>",
           "\t<Rational_Function_Model>", "\t\t<Resource_Reference>",
           '\t\t\t<RESOURCE_TITLE version="2.1">NITF</RESOURCE_TITLE>',
           f"\t\t\t<RESOURCE_ID>{resource_id}</RESOURCE_ID>", "\t\t</Resource_Reference>",
           "\t\t<Global_RFM>", "\t\t\t<RFM_Validity>"]
    if first is not None:
        out += ["\t\t\t\t<ImagetoGround_Validity_Domain>", f"\t\t\t\t\t<FIRST_ROW>{first!r}</FIRST_ROW>",
                f"\t\t\t\t\t<FIRST_COL>{first!r}</FIRST_COL>", "\t\t\t\t</ImagetoGround_Validity_Domain>"]
    out += [f"\t\t\t\t<{k}>{v}</{k}>" for k, v in g.items()] + ["\t\t\t</RFM_Validity>", f"\t\t\t<{block}>"]
    for p in ("samp_num", "samp_den", "line_num", "line_den"):
        out += [f"\t\t\t\t<{p.upper()}_COEFF_{i}>{float(c)!r}</{p.upper()}_COEFF_{i}>"
                for i, c in enumerate(getattr(rpc, p), 1)]
    out += [f"\t\t\t</{block}>", "\t\t</Global_RFM>", "\t</Rational_Function_Model>", "</Dimap_Document>"]
    path.write_text("\n".join(out) + "\n")


def nitf_record(rpc) -> str:
    """The 1,041 characters of a NITF RPC00A/B record of ``rpc``'s numbers (quantised as the
    record quantises: integer pixel offsets, 4 decimals of a degree, 7 significant digits)."""
    def f(v, w, d=0):
        s = f"{v:+0{w}.{d}f}" if d else f"{int(round(v)):0{w}d}"
        assert len(s) == w, (s, w)
        return s

    def c(v):
        m, e = f"{v:+.6E}".split("E")
        return f"{m}E{int(e):+d}" if abs(int(e)) < 10 else f"{v:+.5E}"[:8] + f"E{int(e):+d}"

    head = ("1" + "0001.00" + "0000.10" + f(rpc.line_off, 6) + f(rpc.samp_off, 5) + f(rpc.lat_off, 8, 4)
            + f(rpc.lon_off, 9, 4) + f(rpc.h_off, 5) + f(rpc.line_scale, 6) + f(rpc.samp_scale, 5)
            + f(rpc.lat_scale, 8, 4) + f(rpc.lon_scale, 9, 4) + f(rpc.h_scale, 5))
    record = head + "".join(c(x) for p in POLYS for x in getattr(rpc, p))
    assert len(record) == 1041
    return record


def write_nitf(path, tag, record):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(path, "w", driver="NITF", width=64, height=64, count=1, dtype="uint8",
                           TRE=f"{tag}={record}") as ds:
            ds.write(np.zeros((1, 64, 64), np.uint8))


# ----------------------------------------------------------------- RPC00A in every format
def test_rpc00a_read_as_rpc00b_is_tens_of_pixels_off(original):
    """What the readers must prevent: the same numbers in the other order."""
    assert max_px(original, as_rpc00a(original)) > 10


@pytest.mark.parametrize("fmt", ["geom", "RPB", "DIMAP"])
def test_rpc00a_side_files_are_reordered(original, tmp_path, fmt):
    a = as_rpc00a(original)
    if fmt == "geom":
        write_geom(a, tmp_path / "s.geom", "A")
        write_geom(original, tmp_path / "b.geom", "B")
        files = tmp_path / "s.geom", tmp_path / "b.geom"
    elif fmt == "RPB":
        write_rpb(a, tmp_path / "s.RPB")
        p = tmp_path / "s.RPB"
        p.write_text(p.read_text().replace('SpecId = "RPC00B"', 'specId = "RPC00A"'))
        write_rpb(original, tmp_path / "b.RPB")
        files = p, tmp_path / "b.RPB"
    else:
        write_dimap(a, tmp_path / "RPC_s.XML", resource_id="RPC00A")
        write_dimap(original, tmp_path / "RPC_b.XML")
        files = tmp_path / "RPC_s.XML", tmp_path / "RPC_b.XML"
    got, as_b = read_rpc_file(files[0]), read_rpc_file(files[1])
    assert "RPC00A reordered" in got.source and "RPC00A" not in as_b.source
    assert max_px(got, original) < 1e-9
    assert max_px(as_b, original) < 1e-9


def test_gdal_reads_rpb_and_dimap_rpc00a_as_rpc00b(original, tmp_path):
    """GDAL ignores the order these files state; the project's readers do not."""
    a = as_rpc00a(original)
    write_rpb(a, tmp_path / "scene.RPB")
    rpb = tmp_path / "scene.RPB"
    rpb.write_text(rpb.read_text().replace('SpecId = "RPC00B"', 'specId = "RPC00A"'))
    plain_tif(tmp_path / "scene.tif", 16)
    write_dimap(a, tmp_path / "RPC_foo.XML", resource_id="RPC00A")
    plain_tif(tmp_path / "IMG_foo_R1C1.TIF", 16)
    for img in ("scene.tif", "IMG_foo_R1C1.TIF"):
        with rasterio.open(tmp_path / img) as ds:
            assert ds.rpcs is not None
            gdal = rpc_from_rasterio(ds.rpcs)
        assert max_px(gdal, original) > 10
        assert max_px(read_rpc(tmp_path / img), original) < 1e-9


def test_nitf_rpc00a_record(original, tmp_path):
    """A NITF file with an RPC00A record reads as the same numbers in an RPC00B record do (the
    record quantises them: the reference is the RPC00B file as GDAL reads it)."""
    b_record = nitf_record(original)
    write_nitf(tmp_path / "b.ntf", "RPC00B", b_record)
    with rasterio.open(tmp_path / "b.ntf") as ds:
        quantised = rpc_from_rasterio(ds.rpcs)
    assert max_px(read_rpc(tmp_path / "b.ntf"), quantised) == 0
    a_record = nitf_record(as_rpc00a(quantised))
    write_nitf(tmp_path / "a.ntf", "RPC00A", a_record)
    got = read_rpc(tmp_path / "a.ntf")
    assert "NITF RPC00A" in got.source and "reordered" in got.source
    assert max_px(got, quantised) < 1e-9
    with rasterio.open(tmp_path / "a.ntf") as ds:
        assert max_px(rpc_from_rasterio(ds.rpcs), quantised) > 10      # GDAL's own reading


def test_an_unknown_order_is_refused_with_its_line(original, tmp_path):
    write_rpb(original, tmp_path / "s.RPB")
    p = tmp_path / "s.RPB"
    p.write_text(p.read_text().replace('SpecId = "RPC00B"', 'specId = "RPC00C"'))
    with pytest.raises(InputError, match=r"s\.RPB, line 3: RPB: specId 'RPC00C'.*RPC00A or RPC00B"):
        read_rpc_file(p)
    write_dimap(original, tmp_path / "RPC_s.XML", resource_id="RPC01Z")
    with pytest.raises(InputError, match=r"line 10: DIMAP RPC: RESOURCE_ID 'RPC01Z'"):
        read_rpc_file(tmp_path / "RPC_s.XML")
    write_geom(original, tmp_path / "s.geom", "C")
    with pytest.raises(InputError, match=r"line 2: OSSIM geom: polynomial_format 'C'"):
        read_rpc_file(tmp_path / "s.geom")


# ----------------------------------------------------------------- Pléiades Neo (DIMAP v3)
@pytest.mark.parametrize("first", [None, 0.5])
def test_pleiades_neo_dimap_v3_agrees_with_gdal(original, tmp_path, first):
    """GDAL's sample's shape (``GroundtoImage_Values``, profile ``PNEO_SENSOR``: offsets from
    0), with and without an ``ImagetoGround_Validity_Domain`` (GDAL 3.10 does not read it)."""
    write_dimap(original, tmp_path / "RPC_PNEO.XML", version=3, first=first)
    got = read_rpc_file(tmp_path / "RPC_PNEO.XML")
    assert max_px(got, original) < 1e-9
    plain_tif(tmp_path / "IMG_PNEO_R1C1.TIF", 1024)
    assert read_rpc(tmp_path / "IMG_PNEO_R1C1.TIF").source.startswith("RPC_PNEO.XML")
    with rasterio.open(tmp_path / "IMG_PNEO_R1C1.TIF") as ds:
        assert ds.rpcs is not None
        t = gdal_transformer(ds.rpcs)
    g2i, i2g2i = agreement(got, t, (1024, 1024))
    assert g2i < 1e-8 and i2g2i < 1e-6


def test_dimap_without_a_ground_to_image_model_is_refused(original, tmp_path):
    write_dimap(original, tmp_path / "RPC_x.XML", version=3)
    p = tmp_path / "RPC_x.XML"
    p.write_text(p.read_text().replace("GroundtoImage_Values", "ImagetoGround_Values"))
    with pytest.raises(InputError, match="no ground → image model"):
        read_rpc_file(p)
