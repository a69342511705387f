"""OpenDroneMap gcp_list.txt in every CRS spelling ODM has accepted, and lat/lon column order."""
from __future__ import annotations

import argparse

import pytest

from prismstation.cli import points as points_cli
from prismstation.errors import InputError
from prismstation.io import pointfiles as pfm

LATLON = "gcp_files/ODM_tests/gcp_latlon_valid.txt"      # +proj=longlat, lon lat columns
UTM = "gcp_files/ODM_tests/gcp_utm_north_valid.txt"      # WGS84 UTM 16N
ASP = "gcp_files/asp_StereoPipelineTest/ground_control_points.gcp"  # Antarctica, lon -126


def _with_header(shared_data, tmp_path, rel, header):
    rows = (shared_data / rel).read_text().splitlines()[1:]
    f = tmp_path / "gcp_list.txt"
    f.write_text(header + "\n" + "\n".join(rows) + "\n")
    return f


@pytest.mark.parametrize("header", [
    "WGS84 longlat", "WGS84 lonlat", "wgs84 longlat", "WGS 84 longlat", "EPSG:4326", "epsg:4326",
    "+proj=longlat +datum=WGS84 +no_defs", "'+proj=longlat +ellps=WGS84 +datum=WGS84 +no_defs'",
])
def test_geographic_spellings_read_as_the_real_file(shared_data, tmp_path, header):
    ref = pfm.read_point_file(shared_data / LATLON)
    pf = pfm.read_point_file(_with_header(shared_data, tmp_path, LATLON, header))
    assert pf.format == "odm" and pfm.parse_crs(pf.crs).to_epsg() == 4326
    assert pf.points == ref.points and pf.measurements == ref.measurements
    assert pf.points[0].E == pytest.approx(-85.61322729531112) and pf.warnings == ()


@pytest.mark.parametrize("header", [
    "WGS84 UTM 16N", "WGS84 UTM 16 N", "wgs84 utm 16n", "EPSG:32616",
    "+proj=utm +zone=16 +datum=WGS84 +units=m +no_defs",
    "+proj=utm +zone=16 +datum=WGS84 +units=m +no_defs=True",  # as ODM builds it from WGS84 UTM
])
def test_projected_spellings_read_as_the_real_file(shared_data, tmp_path, header):
    ref = pfm.read_point_file(shared_data / UTM)
    pf = pfm.read_point_file(_with_header(shared_data, tmp_path, UTM, header))
    assert pfm.parse_crs(pf.crs).to_epsg() == 32616
    assert pf.points == ref.points and pf.points[0].E == pytest.approx(609925.8180680283)


def test_south_zone_and_bad_zone(tmp_path):
    assert pfm.parse_crs("WGS84 UTM 32N").to_epsg() == 32632
    assert pfm.parse_crs("WGS84 UTM 32S").to_epsg() == 32732
    f = tmp_path / "gcp_list.txt"
    f.write_text("WGS84 UTM 61N\n1 2 3 4 5 a.jpg\n")
    with pytest.raises(InputError, match="UTM zone 61") as err:
        pfm.read_point_file(f)
    assert err.value.line == 1


def _asp_as_odm(shared_data, tmp_path, header, lat_first):
    """The real ASP points (lat -77, lon -126) written as an ODM file, columns in either order."""
    asp = pfm.read_point_file(shared_data / ASP)
    rows = [f"{p.N} {p.E} {p.H} 10 20 a.tif {p.id}" if lat_first else
            f"{p.E} {p.N} {p.H} 10 20 a.tif {p.id}" for p in asp.points]
    f = tmp_path / "gcp_list.txt"
    f.write_text(header + "\n" + "\n".join(rows) + "\n")
    return asp, f


@pytest.mark.parametrize("header", ["WGS84 longlat", "EPSG:4326", "+proj=longlat +datum=WGS84"])
def test_latitude_first_columns_are_swapped_with_a_warning(shared_data, tmp_path, header):
    asp, f = _asp_as_odm(shared_data, tmp_path, header, lat_first=True)
    pf = pfm.read_point_file(f)
    assert [(p.E, p.N) for p in pf.points] == [(p.E, p.N) for p in asp.points]
    assert len(pf.warnings) == 1 and "line 2" in pf.warnings[0] and "geo_y" in pf.warnings[0]
    _, g = _asp_as_odm(shared_data, tmp_path, header, lat_first=False)  # right order: no warning
    assert pfm.read_point_file(g).warnings == ()


def test_header_saying_latlon_is_obeyed_and_written_back(shared_data, tmp_path):
    asp, f = _asp_as_odm(shared_data, tmp_path, "WGS84 latlon", lat_first=True)
    pf = pfm.read_point_file(f)
    assert [(p.E, p.N) for p in pf.points] == [(p.E, p.N) for p in asp.points] and not pf.warnings
    out = tmp_path / "back.txt"
    pfm.write_point_file(pf, out)
    assert out.read_text().splitlines()[1].split()[:2] == f.read_text().splitlines()[1].split()[:2]


def test_ambiguous_order_stays_as_the_header_says(shared_data, tmp_path):
    # Michigan: lat 44.7, lon -85.6, both within ±90: the file's lat-first rows cannot be told
    src = (shared_data / LATLON).read_text().splitlines()
    rows = [" ".join([r.split()[1], r.split()[0]] + r.split()[2:]) for r in src[1:]]
    f = tmp_path / "gcp_list.txt"
    f.write_text("WGS84 longlat\n" + "\n".join(rows) + "\n")
    pf = pfm.read_point_file(f)
    assert pf.points[0].E == pytest.approx(44.701151842605441) and pf.warnings == ()


def test_both_columns_beyond_90_names_the_line(tmp_path):
    f = tmp_path / "gcp_list.txt"
    f.write_text("EPSG:4326\n-85.6 44.7 150 1 2 a.jpg p\n-126.1 -97.2 150 1 2 a.jpg q\n")
    with pytest.raises(InputError, match="latitude") as err:
        pfm.read_point_file(f)
    assert err.value.line == 3


def test_cli_points_prints_the_warning(shared_data, tmp_path, capsys):
    _, f = _asp_as_odm(shared_data, tmp_path, "WGS84 longlat", lat_first=True)
    parser = argparse.ArgumentParser(prog="prismstation")
    points_cli.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["points", str(f), "-o", str(tmp_path / "out.gcp")])
    assert args.func(args) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: ") and "read geo_x as latitude and geo_y as longitude" in err
    back = pfm.read_point_file(tmp_path / "out.gcp")   # ASP writes lat lon: read back unswapped
    assert back.warnings == () and back.points[0].E == pytest.approx(-126.181)


def test_asp_file_with_longitude_first_is_swapped(shared_data, tmp_path):
    src = (shared_data / ASP).read_text().splitlines()
    swapped = []
    for row in src:
        c = [v.strip() for v in row.split(",")]
        c[4] = "2" if c[0] == "0" else c[4]   # one distinct σ_lat, to follow through the swap
        swapped.append(", ".join([c[0], c[2], c[1], c[3], c[5], c[4]] + c[6:]))
    f = tmp_path / "lonlat.gcp"
    f.write_text("\n".join(swapped) + "\n")
    ref, pf = pfm.read_point_file(shared_data / ASP), pfm.read_point_file(f)
    assert [(p.E, p.N, p.H) for p in pf.points] == [(p.E, p.N, p.H) for p in ref.points]
    assert pf.measurements == ref.measurements
    assert pf.points[0].extra == {"sigma_lat": 2.0, "sigma_lon": 1.0}
    (w,) = pf.warnings
    assert "column 2 (lat) holds longitudes (e.g. -126.181 on line 1)" in w
