"""Other tools' point files: every real example reads, round-trips, converts; bad lines are named."""
from __future__ import annotations

import math

import pytest

import argparse

from prismstation.cli import points as points_cli
from prismstation.errors import InputError
from prismstation.io import pointfiles as pfm

REAL = "gcp_files"


def _real(shared_data, rel):
    return shared_data / REAL / rel


def _by_id(pf):
    return {p.id: p for p in pf.points}


def _same(a, b, px_tol=1e-9, xy_tol=0.0, h_tol=1e-9):
    assert [p.id for p in a.points] == [p.id for p in b.points]
    for p, q in zip(a.points, b.points):
        assert (p.kind, p.height_kind) == (q.kind, q.height_kind)
        assert abs(p.E - q.E) <= xy_tol and abs(p.N - q.N) <= xy_tol, (p, q)
        assert abs(p.H - q.H) <= h_tol, (p, q)
    key = lambda m: (m.id, m.view)  # noqa: E731
    ma, mb = sorted(a.measurements, key=key), sorted(b.measurements, key=key)
    assert [key(m) for m in ma] == [key(m) for m in mb]
    for m, n in zip(ma, mb):
        assert abs(m.x - n.x) <= px_tol and abs(m.y - n.y) <= px_tol, (m, n)


# ------------------------------------------------------------------ every real example reads


def test_odm_gcp_list_with_comments(shared_data):
    pf = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_list.txt"))
    assert pf.format == "odm" and pf.crs == "EPSG:32617"
    # by hand: HV01..HV05; the commented-out 'badHV01' row is skipped; 3+4+3+5+3 rows
    assert [p.id for p in pf.points] == ["HV01", "HV02", "HV03", "HV04", "HV05"]
    assert len(pf.measurements) == 18
    hv04 = _by_id(pf)["HV04"]
    assert (hv04.E, hv04.N, hv04.H) == (274920.710, 4603258.802, 400.0)
    m = [m for m in pf.measurements if m.id == "HV04" and m.view == "DJI_0063.JPG"]
    # file row "274920.710 4603258.802 400 2202.425 1319.122 DJI_0063.JPG HV04":
    # OpenSfM puts pixel centres at integers, docs/model.md at +0.5
    assert len(m) == 1 and m[0].x == pytest.approx(2202.925) and m[0].y == pytest.approx(1319.622)
    assert not any(m.view == "1JI_0076.JPG" and m.y < 0 for m in pf.measurements)


def test_odm_unnamed_rows_group_by_coordinates(shared_data):
    pf = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_utm_north_valid.txt"))
    assert pf.crs == "WGS84 UTM 16N"
    assert len(pf.points) == 1 and len(pf.measurements) == 3
    assert {m.view for m in pf.measurements} == {"DJI_0002.JPG", "DJI_0003.JPG", "DJI_0004.JPG"}
    p = pf.points[0]
    assert (p.E, p.N, p.H) == (609925.8180680283, 4950688.771811823, 171.662982)
    bellus = pfm.read_point_file(_real(shared_data, "odm_data_bellus/gcp_list.txt"))
    assert len(bellus.points) == 4 and len(bellus.measurements) == 4   # trailing blank tolerated
    assert bellus.points[2].E == 440934.5930160007 and bellus.points[2].H == 350.638872
    latlon = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_latlon_valid.txt"))
    assert len(latlon.points) == 2
    assert latlon.points[1].E == -85.612848642726888 and latlon.points[1].N == 44.701023803183617


def test_odm_us_feet_grid_matches_the_utm_file(shared_data):
    """The Michigan (ft) example is the same point as the UTM 16N example: E/N through pyproj,
    the height from feet (563.1987598425 ft x 0.3048 m/ft)."""
    feet = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_michigan_feet_valid.txt"))
    assert feet.crs == "EPSG:2251"
    assert feet.points[0].H == pytest.approx(563.1987598425 * 0.3048, abs=1e-9)
    utm = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_utm_north_valid.txt"))
    conv = pfm.convert_point_file(feet, "EPSG:32616")
    p, q = conv.points[0], utm.points[0]
    assert math.hypot(p.E - q.E, p.N - q.N) < 0.001
    assert p.H == pytest.approx(q.H, abs=1e-6)


def test_asp_gcp(shared_data):
    pf = pfm.read_point_file(_real(shared_data, "asp_StereoPipelineTest/ground_control_points.gcp"))
    assert pf.format == "asp" and pf.crs == "EPSG:4326"
    assert len(pf.points) == 12 and len(pf.measurements) == 24
    p9 = _by_id(pf)["9"]   # "9, -77.1213, -126.156, 2369.71, 1, 1, 1, ..."
    assert (p9.N, p9.E, p9.H, p9.height_kind) == (-77.1213, -126.156, 2369.71, "ellipsoidal")
    assert p9.sigma_h_m == 1.0
    m = [m for m in pf.measurements if m.id == "9" and m.view == "mt_sidley_48.tif"][0]
    assert (m.x, m.y, m.sigma_px) == (pytest.approx(8095.51), pytest.approx(7332.32), 1.0)


# ------------------------------------------------------------------ round trips


ALL = ["ODM_tests/gcp_list.txt", "ODM_tests/gcp_latlon_valid.txt",
       "ODM_tests/gcp_michigan_feet_valid.txt", "ODM_tests/gcp_utm_north_valid.txt",
       "odm_data_bellus/gcp_list.txt", "asp_StereoPipelineTest/ground_control_points.gcp"]


@pytest.mark.parametrize("rel", ALL)
def test_round_trip_same_format(shared_data, tmp_path, rel):
    src = _real(shared_data, rel)
    a = pfm.read_point_file(src)
    out = tmp_path / src.name
    pfm.write_point_file(a, out, a.format)
    b = pfm.read_point_file(out)
    assert b.format == a.format and b.crs == a.crs
    _same(a, b)
    # and the text is stable from then on
    out2 = tmp_path / ("again_" + src.name)
    pfm.write_point_file(b, out2, b.format)
    assert out2.read_text() == out.read_text()


def test_round_trip_through_qgis_one_view(shared_data, tmp_path):
    a = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_list.txt"))
    out = tmp_path / "dji68.points"
    pfm.write_point_file(a, out, view="DJI_0068.JPG")
    text = out.read_text().splitlines()
    assert text[0].startswith("#CRS: ") and text[1].startswith("mapX,mapY,sourceX,sourceY,enable")
    # QGIS y is negative downwards: row 514.215 (ODM) -> 514.715 (MODEL) -> sourceY -514.715
    assert text[2].split(",")[:5] == ["274914.738", "4603349.014", "1230.176", "-514.715", "1"]
    b = pfm.read_point_file(out, view="DJI_0068.JPG")
    assert b.crs and pfm.parse_crs(b.crs).to_epsg() == 32617
    only = [m for m in a.measurements if m.view == "DJI_0068.JPG"]
    ids = {m.id for m in only}
    assert {p.id for p in b.points} == ids
    for p in b.points:
        q = _by_id(a)[p.id]
        assert (p.E, p.N, p.H) == (q.E, q.N, q.H)
    for m in b.measurements:
        n = [n for n in only if n.id == m.id][0]
        assert m.x == pytest.approx(n.x, abs=1e-9) and m.y == pytest.approx(n.y, abs=1e-9)


def test_qgis_plain_file_and_disabled_points(tmp_path):
    f = tmp_path / "old.points"
    f.write_text("mapX,mapY,pixelX,pixelY,enable\n500010.5,4600020.25,10.5,-20.75,1\n"
                 "500100,4600000,100,-300,0\n")
    pf = pfm.read_point_file(f)
    assert pf.crs is None and [p.kind for p in pf.points] == ["GCP", "ICP"]
    assert (pf.measurements[0].x, pf.measurements[0].y) == (10.5, 20.75)
    out = tmp_path / "again.points"
    pfm.write_point_file(pf, out)
    _same(pf, pfm.read_point_file(out))


def test_odm_to_asp_and_back_converts_crs(shared_data, tmp_path):
    a = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_list.txt"))
    asp = tmp_path / "x.gcp"
    pfm.write_point_file(a, asp)        # ASP is geographic: converted on the way
    b = pfm.read_point_file(asp)
    assert b.crs == "EPSG:4326" and -84 < b.points[0].E < -83 and 41 < b.points[0].N < 42
    back = pfm.convert_point_file(b, "EPSG:32617")
    _same(a, back, px_tol=1e-9, xy_tol=1e-4, h_tol=1e-9)


def test_csv_round_trip(tmp_path):
    f = tmp_path / "g.csv"
    f.write_text("id,E,N,H,kind,height,sigma_xy_m,sigma_h_m,note\n"
                 "A,512000.5,4601000.25,123.5,GCP,orthometric,0.5,,road\n"
                 "B,513000,4602000,99,ICP,,,1.5,\n")
    a = pfm.read_point_file(f)
    assert [p.kind for p in a.points] == ["GCP", "ICP"]
    assert a.points[0].height_kind == "orthometric" and a.points[1].height_kind == "ellipsoidal"
    assert a.points[0].extra == {"note": "road"} and a.points[1].sigma_h_m == 1.5
    out = tmp_path / "h.csv"
    pfm.write_point_file(a, out)
    b = pfm.read_point_file(out)
    assert a.points == b.points and b.points[0].extra == {"note": "road"}


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("name,text,line,word", [
    ("bad.txt", "EPSG:32617\n# c\n1 2 3 4 5 a.jpg p\n1 2 x 4 5 a.jpg q\n", 4, "geo_z"),
    ("short.txt", "EPSG:32617\n1 2 3 4 5\n", 2, "geo_x"),
    ("crs.txt", "EPSG:99999999\n1 2 3 4 5 a.jpg\n", 1, "coordinate system"),
    ("b.gcp", "0, -77.1, -126.1, 10, 1, 1, 1, a.tif, 1, 2, 1, 1\n1, -77.1, oops, 10, 1, 1, 1, "
     "a.tif, 1, 2, 1, 1\n", 2, "longitude"),
    ("c.gcp", "0, -97.1, -126.1, 10, 1, 1, 1, a.tif, 1, 2, 1, 1\n", 1, "latitude"),
    ("d.points", "mapX,mapY,sourceX,sourceY,enable\n1,2,3,-4,1\n1,2,3\n", 3, "expected"),
    ("e.points", "mapX,mapY,sourceX,sourceY,enable\n1,2,3,-4,yes\n", 2, "enable"),
    ("f.csv", "id,E,N,H\nA,1,2,3\nA,1,2,3\n", 3, "twice"),
])
def test_malformed_names_file_and_line(tmp_path, name, text, line, word):
    f = tmp_path / name
    f.write_text(text)
    with pytest.raises(InputError) as err:
        pfm.read_point_file(f)
    assert err.value.line == line and err.value.file == str(f)
    assert word in err.value.problem
    assert f"{f}, line {line}: " in str(err.value)


def main(argv):
    """Run ``prismstation points`` alone (other sub-commands may be under construction)."""
    parser = argparse.ArgumentParser(prog="prismstation")
    points_cli.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:  # what prismstation.cli.main does with a PrismError
        print(f"prismstation {args.command}: {exc}", file=__import__("sys").stderr)
        return 2


def test_cli_converts_and_reports_bad_input(shared_data, tmp_path, capsys):
    src = _real(shared_data, "ODM_tests/gcp_michigan_feet_valid.txt")
    out = tmp_path / "m.txt"
    assert main(["points", str(src), "-o", str(out), "--to-crs", "WGS84 UTM 16N"]) == 0
    pf = pfm.read_point_file(out)
    assert pf.crs == "WGS84 UTM 16N"
    row = out.read_text().splitlines()[1].split()   # metres now: UTM has no feet
    assert float(row[2]) == pytest.approx(171.662982, abs=1e-6)
    assert float(row[0]) == pytest.approx(609925.818, abs=1e-3)
    csv_out, m_out = tmp_path / "g.csv", tmp_path / "m.csv"
    assert main(["points", str(src), "-o", str(csv_out), "--measurements", str(m_out)]) == 0
    assert csv_out.read_text().splitlines()[0] == "id,E,N,H,kind,height,sigma_xy_m,sigma_h_m"
    assert m_out.read_text().splitlines()[1] == "gcp1,DJI_0002.JPG,1331.5,350.5,"
    bad = tmp_path / "bad.txt"
    bad.write_text("EPSG:32617\n1 2 3 4 nope a.jpg\n")
    assert main(["points", str(bad), "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.txt, line 2" in err[0] and "im_y" in err[0]


def test_odm_written_in_a_feet_grid_gives_feet_heights(shared_data, tmp_path):
    utm = pfm.read_point_file(_real(shared_data, "ODM_tests/gcp_utm_north_valid.txt"))
    out = tmp_path / "ft.txt"
    pfm.write_point_file(pfm.convert_point_file(utm, "EPSG:2251"), out)
    lines = out.read_text().splitlines()
    assert lines[0] == "EPSG:2251"
    x, y, z = (float(v) for v in lines[1].split()[:3])
    # the Michigan example holds this very point: 26607594.75468351 -26813.882366498266 563.1987598425
    assert x == pytest.approx(26607594.75468351, abs=0.01)
    assert y == pytest.approx(-26813.882366498266, abs=0.01)
    assert z == pytest.approx(563.1987598425, abs=1e-6)


def test_odm_comment_before_crs_line(tmp_path):
    f = tmp_path / "gcp_list.txt"
    f.write_text("# made by hand\nEPSG:32629\n512000 4601000 100 10 20 a.jpg P1\n")
    pf = pfm.read_point_file(f)
    assert pf.format == "odm" and pf.crs == "EPSG:32629" and pf.points[0].id == "P1"
