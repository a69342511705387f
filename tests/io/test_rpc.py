"""The RPC readers against GDAL's RPC transformer on every real sample, and bad RPC files."""
from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest
import rasterio
from rasterio.enums import TransformDirection
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer

from prismstation.errors import InputError
from prismstation.io.rpc import find_rpc_files, read_rpc, read_rpc_file

PHR = "PHR1B_P_201709281038393_SEN_PRG_FC_178609-001"
TOL_PX = 1e-3


def gdal_transformer(rpcs):
    # GDAL iterates image → ground to 0.1 px by default; ask for far better than the test's 1e-3
    return RPCTransformer(rpcs, RPC_PIXEL_ERROR_THRESHOLD=1e-7, RPC_MAX_ITERATIONS=100)


def image_samples(rpc, shape=None, n=400, seed=0):
    """Image points over the image (or, without one, over the RPC's normalised image domain)
    and heights over the RPC's height range."""
    rng = np.random.default_rng(seed)
    if shape is not None:
        x, y = rng.uniform(0, shape[1], n), rng.uniform(0, shape[0], n)
    else:
        x = rpc.samp_off + 0.5 + rng.uniform(-0.9, 0.9, n) * rpc.samp_scale
        y = rpc.line_off + 0.5 + rng.uniform(-0.9, 0.9, n) * rpc.line_scale
    h = rpc.h_off + rng.uniform(-0.9, 0.9, n) * rpc.h_scale
    return x, y, h


def agreement(rpc, transformer, shape=None, dx=0.0, dy=0.0):
    """Max differences (px) between our model and GDAL's: ground → image on ground points of
    the image's footprint, and image → ground (each) → image (the other). ``dx, dy``: our
    image frame minus GDAL's (a crop)."""
    x, y, h = image_samples(rpc, shape)
    lon, lat = rpc.localize(x, y, h)
    gx, gy = transformer._transform(lon, lat, h, transform_direction=TransformDirection.reverse)
    mx, my = rpc.project(lon, lat, h)
    g2i = max(np.abs(np.asarray(gx) + dx - mx).max(), np.abs(np.asarray(gy) + dy - my).max())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        glon, glat = transformer._transform(x - dx, y - dy, h,
                                            transform_direction=TransformDirection.forward)
    glon, glat = np.asarray(glon), np.asarray(glat)
    ok = np.isfinite(glon) & np.isfinite(glat)
    assert ok.all(), "GDAL could not take every point image → ground"
    bx, by = rpc.project(glon[ok], glat[ok], h[ok])
    gdal_then_ours = max(np.abs(bx - x[ok]).max(), np.abs(by - y[ok]).max())
    ours_then_gdal = max(np.abs(np.asarray(gx) + dx - x).max(), np.abs(np.asarray(gy) + dy - y).max())
    return g2i, max(gdal_then_ours, ours_then_gdal)


@pytest.mark.parametrize("name", ["pleiades_triplet/img_01.tif", "pleiades_triplet/img_02.tif",
                                  "pleiades_triplet/img_03.tif", "pleiades_pair_reunion/img_01.tif",
                                  "pleiades_pair_reunion/img_02.tif", "rpc_formats/wv3_20.NTF"])
def test_metadata_rpcs_agree_with_gdal(shared_data, name):
    path = shared_data / name
    rpc = read_rpc(path)
    with rasterio.open(path) as ds:
        shape, t = ds.shape, gdal_transformer(ds.rpcs)
    g2i, i2g2i = agreement(rpc, t, shape)
    assert g2i < TOL_PX and i2g2i < TOL_PX


@pytest.mark.parametrize("side", [f"RPC_{PHR}.XML", f"{PHR}.geom"])
def test_dimap_xml_and_geom_agree_with_gdal_reading_the_xml(shared_data, side):
    """GDAL reads the DIMAP XML beside the tif (its 1-based offsets made 0-based); our DIMAP
    and OSSIM readers must give the same model."""
    d = shared_data / "rpc_formats"
    rpc = read_rpc_file(d / side)
    with rasterio.open(d / f"{PHR}.tif") as ds:
        assert ds.rpcs is not None
        shape, t = ds.shape, gdal_transformer(ds.rpcs)
    g2i, i2g2i = agreement(rpc, t, shape)
    assert g2i < TOL_PX and i2g2i < TOL_PX
    assert read_rpc(d / f"{PHR}.tif").source.startswith(f"{PHR}.geom")


@pytest.mark.parametrize("img, origin", [("img1", (20500, 5000)), ("img2", (20501, 5476))])
def test_geom_crop_placed_by_its_geotransform(shared_data, img, origin):
    """GDAL does not read .geom: its transformer gets the same coefficients through its own
    RPC metadata keys, in full-image pixels; our model of the crop is that one moved by the
    crop's origin."""
    d = shared_data / "pleiades_pair_gizeh"
    full = read_rpc_file(d / f"{img}.geom")
    crop = read_rpc(d / f"{img}.tif")
    assert "crop at" in crop.source
    t = gdal_transformer(RPC.from_gdal(full.to_gdal_dict()))
    with rasterio.open(d / f"{img}.tif") as ds:
        shape = ds.shape
    g2i, i2g2i = agreement(crop, t, shape, dx=-origin[0], dy=-origin[1])
    assert g2i < TOL_PX and i2g2i < TOL_PX


def test_jaxa_alos_text_agrees_with_gdal_alos_reader(shared_data, tmp_path):
    """GDAL's ALOS reader finds RPC-<id>.txt beside IMG-01-<id>.tif when the product's HDR
    file is there too; so do we (without the HDR)."""
    shutil.copy(shared_data / "rpc_formats" / "RPC-md_alos.txt", tmp_path / "RPC-md_alos.txt")
    img = tmp_path / "IMG-01-md_alos.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(img, "w", driver="GTiff", width=16, height=16, count=1,
                           dtype="uint8") as ds:
            ds.write(np.zeros((1, 16, 16), np.uint8))
    assert find_rpc_files(img) == [tmp_path / "RPC-md_alos.txt"]
    rpc = read_rpc(img)
    (tmp_path / "HDR-md_alos.txt").write_text("")
    with rasterio.open(img) as ds:
        assert ds.rpcs is not None, "GDAL's ALOS reader did not find the RPC file"
        t = gdal_transformer(ds.rpcs)
    g2i, i2g2i = agreement(rpc, t)
    assert g2i < TOL_PX and i2g2i < TOL_PX
    assert (rpc.line_off, rpc.samp_off, rpc.h_scale) == (4000.0, 3639.0, 3158.0)


# ----------------------------------------------------------------- writers for the text forms
def write_rpb(rpc, path):
    g = rpc.to_gdal_dict()
    keys = [("lineOffset", "LINE_OFF"), ("sampOffset", "SAMP_OFF"), ("latOffset", "LAT_OFF"),
            ("longOffset", "LONG_OFF"), ("heightOffset", "HEIGHT_OFF"), ("lineScale", "LINE_SCALE"),
            ("sampScale", "SAMP_SCALE"), ("latScale", "LAT_SCALE"), ("longScale", "LONG_SCALE"),
            ("heightScale", "HEIGHT_SCALE")]
    out = ['satId = "PHR1A";', 'bandId = "P";', 'SpecId = "RPC00B";', "BEGIN_GROUP = IMAGE",
           "\terrBias = 1.0;", "\terrRand = 0.1;"]
    out += [f"\t{k} = {g[v]};" for k, v in keys]
    for k, v in (("lineNumCoef", "LINE_NUM_COEFF"), ("lineDenCoef", "LINE_DEN_COEFF"),
                 ("sampNumCoef", "SAMP_NUM_COEFF"), ("sampDenCoef", "SAMP_DEN_COEFF")):
        c = g[v].split()
        out.append(f"\t{k} = (")
        out += [f"\t\t\t{x}," for x in c[:-1]] + [f"\t\t\t{c[-1]});"]
    out += ["END_GROUP = IMAGE", "END;"]
    path.write_text("\n".join(out) + "\n")


def write_rpc_txt(rpc, path):
    g = rpc.to_gdal_dict()
    units = {"OFF": "", "SCALE": ""}
    out = [f"{k}: {g[k]} {units.get(k.split('_')[-1], '')}".rstrip()
           for k in ("LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF", "LINE_SCALE",
                     "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE")]
    for k in ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF"):
        out += [f"{k}_{i}: {c}" for i, c in enumerate(g[k].split(), 1)]
    path.write_text("\n".join(out) + "\n")


def plain_tif(path, n=64):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="uint8") as ds:
            ds.write(np.zeros((1, n, n), np.uint8))


@pytest.mark.parametrize("suffix, writer", [(".RPB", write_rpb), ("_RPC.TXT", write_rpc_txt)])
def test_rpb_and_rpc_txt_agree_with_gdal(shared_data, tmp_path, suffix, writer):
    """The triplet's first RPC written as a side file beside a plain tif: GDAL reads the side
    file, so do we."""
    src = read_rpc(shared_data / "pleiades_triplet" / "img_01.tif")
    img = tmp_path / "scene.tif"
    plain_tif(img, 1024)
    writer(src, tmp_path / f"scene{suffix}")
    rpc = read_rpc(img)
    assert rpc.source.startswith(f"scene{suffix}")
    with rasterio.open(img) as ds:
        assert ds.rpcs is not None
        t = gdal_transformer(ds.rpcs)
    g2i, i2g2i = agreement(rpc, t, (1024, 1024))
    assert g2i < TOL_PX and i2g2i < TOL_PX


# ----------------------------------------------------------------- bad files
def test_bad_geom_files_name_file_line_and_problem(shared_data, tmp_path):
    good = (shared_data / "pleiades_pair_gizeh" / "img1.geom").read_text().splitlines()
    cases = {
        "missing": ([s for s in good if not s.startswith("lat_scale:")], "lat_scale is missing", None),
        "count": ([s for s in good if not s.startswith("samp_num_coeff_07:")],
                  "samp_num_coeff needs 20 coefficients, found 19 (missing samp_num_coeff 7)", None),
        "nan": ([s.replace("0.709595310594016", "abc") if s.startswith("line_num_coeff_01") else s
                 for s in good], "line_num_coeff 1: '-abc' is not a number", "line_num_coeff_01"),
        "zero": (["line_scale:  0" if s.startswith("line_scale:") else s for s in good],
                 "line_scale is zero", "line_scale:"),
        "rot": (["adjustment_0.adj_param_4.parameter:  0.5"
                 if s.startswith("adjustment_0.adj_param_4.parameter") else s for s in good], "map_rotation", "adjustment_0.adj_param_4.description"),
    }
    for name, (lines, problem, key) in cases.items():
        p = tmp_path / f"{name}.geom"
        p.write_text("\n".join(lines) + "\n")
        with pytest.raises(InputError) as e:
            read_rpc_file(p)
        assert problem in str(e.value) and str(p) in str(e.value), (name, str(e.value))
        if key is not None:
            assert e.value.line == next(i for i, s in enumerate(lines, 1) if s.startswith(key))


def test_geom_image_offsets_are_applied(shared_data, tmp_path):
    text = (shared_data / "pleiades_pair_gizeh" / "img1.geom").read_text()
    text = text.replace("adj_param_0.parameter:  0", "adj_param_0.parameter:  0.2")  # 10 px
    text = text.replace("adj_param_1.center:  0", "adj_param_1.center:  -3")
    p = tmp_path / "moved.geom"
    p.write_text(text)
    a, b = read_rpc_file(shared_data / "pleiades_pair_gizeh" / "img1.geom"), read_rpc_file(p)
    assert b.line_off - a.line_off == pytest.approx(10.0) and b.samp_off - a.samp_off == -3.0


def test_bad_side_files(shared_data, tmp_path):
    src = read_rpc(shared_data / "pleiades_triplet" / "img_01.tif")
    rpb = tmp_path / "a.RPB"
    write_rpb(src, rpb)
    rpb.write_text(rpb.read_text().replace("lineScale = ", "lineScale = x"))
    with pytest.raises(InputError, match=r"a\.RPB, line \d+: lineScale: 'x.*' is not a number"):
        read_rpc_file(rpb)
    txt = tmp_path / "a_RPC.TXT"
    write_rpc_txt(src, txt)
    lines = txt.read_text().splitlines()
    txt.write_text("\n".join(s for s in lines if not s.startswith("SAMP_DEN_COEFF_20")))
    with pytest.raises(InputError, match="SAMP_DEN_COEFF needs 20 coefficients, found 19"):
        read_rpc_file(txt)
    txt.write_text("\n".join("HEIGHT_SCALE: +0000.0 meters" if s.startswith("HEIGHT_SCALE")
                             else s for s in lines))
    with pytest.raises(InputError, match="HEIGHT_SCALE is zero") as e:
        read_rpc_file(txt)
    assert e.value.line == 10
    xml = (shared_data / "rpc_formats" / f"RPC_{PHR}.XML").read_text()
    bad = tmp_path / "RPC_bad.XML"
    bad.write_text(xml.replace("<LAT_OFF>43.67726387230638</LAT_OFF>", ""))
    with pytest.raises(InputError, match="LAT_OFF is missing"):
        read_rpc_file(bad)
    bad.write_text(xml.replace("<LINE_NUM_COEFF_3>", "<LINE_NUM_COEFF_3>1e").replace(
        "</Dimap_Document>", "</Dimap_Document>"))
    with pytest.raises(InputError, match="LINE_NUM_COEFF 3: .* is not a number") as e:
        read_rpc_file(bad)
    assert e.value.line is not None and "LINE_NUM_COEFF_3" in xml.splitlines()[e.value.line - 1]
    bad.write_text(xml[:500])
    with pytest.raises(InputError, match="not well-formed XML"):
        read_rpc_file(bad)
    alos = (shared_data / "rpc_formats" / "RPC-md_alos.txt").read_text()
    short = tmp_path / "RPC-short.txt"
    short.write_text(alos[:900])
    with pytest.raises(InputError, match="needs 1026"):
        read_rpc_file(short)
    short.write_text(alos[:11] + "+55.8x51" + alos[19:])
    with pytest.raises(InputError, match=r"RPC-short\.txt, line 1: LAT_OFF: '\+55\.8x51'"):
        read_rpc_file(short)


def test_image_without_rpcs(tmp_path):
    img = tmp_path / "plain.tif"
    plain_tif(img)
    with pytest.raises(InputError, match="no RPCs found"):
        read_rpc(img)
    with pytest.raises(InputError, match="not found"):
        read_rpc(tmp_path / "none.tif")
