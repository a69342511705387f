"""io/csvtable: one set of table rules for every reader, every bad line returned."""
from __future__ import annotations

import pytest

from prismstation.errors import InputError
from prismstation.io import pointfiles as pfm
from prismstation.io.csvtable import guess_delimiter, read_table, records, split_text
from prismstation.io.points import read_ground_points, read_measurements
from prismstation.io.rectify_io import read_point_pairs

# semicolons, a BOM, a comment, a blank line, header names in another case
POINTS = "\ufeff# survey 2024\nID;e;N;h;Kind\n\nA1;540000.5;4560000.25;100;GCP\nA2;540100;4560100;110;ICP\n"
MEAS = "# digitised\nid\tview\tX\tY\nA1\tN\t10.5\t20.25\nA2\tN\t30\t40\n"


@pytest.mark.parametrize("delim", [",", ";", "\t", "|"])
def test_guess_delimiter(delim):
    lines = [delim.join(r) for r in (["id", "E", "N"], ["a", "1,5" if delim != "," else "1", "2"])]
    assert guess_delimiter(lines) == delim
    assert guess_delimiter(["id  E   N", "a 1 2"]) == " " and guess_delimiter([]) == ","


def test_table_keeps_file_line_numbers_and_comments():
    t = split_text(POINTS.lstrip("\ufeff"), path="p.csv")
    assert t.delimiter == ";" and t.header_line == 2 and t.columns == ["ID", "e", "N", "h", "Kind"]
    assert [no for no, _ in t.rows] == [4, 5] and t.comments == [(1, "# survey 2024")]
    t = split_text("a 1 2\nb 3\n", " ", header=False)
    assert t.columns == ["column 1", "column 2", "column 3"]
    rows, errs = records(t, ("id",), mapping={"id": "column 1"})
    assert [r.line for r in rows] == [1] and str(errs[0]) == "line 2: 2 fields where the widest row has 3"


def test_the_same_file_reads_the_same_in_every_reader(tmp_path):
    p, m = tmp_path / "p.txt", tmp_path / "m.txt"
    p.write_text(POINTS, encoding="utf-8")
    m.write_text(MEAS)
    gp = read_ground_points(p)
    assert [(g.id, g.E, g.N, g.H, g.kind) for g in gp] == [
        ("A1", 540000.5, 4560000.25, 100.0, "GCP"), ("A2", 540100.0, 4560100.0, 110.0, "ICP")]
    assert pfm.read_point_file(p, "csv").points == tuple(gp)
    pairs = read_point_pairs(p, m)
    assert pairs.ids == ("A1", "A2") and pairs.xy.tolist() == [[10.5, 20.25], [30.0, 40.0]]
    assert pairs.is_check.tolist() == [False, True] and pairs.h.tolist() == [100.0, 110.0]
    assert [(x.id, x.x) for x in read_measurements(m, views=["N"])] == [("A1", 10.5), ("A2", 30.0)]


BAD = "id,E,N,H\nA1,1,2,3\nA2,1,x,3\nA3,1,2\nA1,1,2,3\nA5,1,2,inf\n"


@pytest.mark.parametrize("read", [read_ground_points, lambda f: pfm.read_point_file(f, "csv"),
                                  lambda f: read_point_pairs(f, f.with_name("m.csv"))])
def test_every_reader_names_the_first_bad_line_and_counts_the_rest(tmp_path, read):
    f = tmp_path / "bad.csv"
    f.write_text(BAD)
    (tmp_path / "m.csv").write_text("id,view,x,y\nA1,N,1,2\n")
    with pytest.raises(InputError) as err:
        read(f)
    assert err.value.file == str(f) and err.value.line == 3
    assert err.value.problem.endswith("(and 3 more problems: lines 4, 5, 6)")


def test_records_returns_every_bad_line(tmp_path):
    f = tmp_path / "bad.csv"
    f.write_text(BAD)
    rows, errs = records(read_table(f), ("id", "E", "N", "H"), ("id", "E", "N", "H"))
    assert [r.line for r in rows] == [2, 3, 5, 6] and [(e.line, e.problem) for e in errs] == [
        (4, "3 fields where the header has 4")]
    with pytest.raises(InputError, match="not a finite number"):
        rows[3].number("H")
    with pytest.raises(InputError, match="header lacks column sigma") as err:
        records(read_table(f), ("id",), ("sigma",))
    assert err.value.line == 1


def test_unreadable_and_empty_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_table(tmp_path / "none.csv")
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00a")
    with pytest.raises(InputError, match="not UTF-8"):
        read_table(tmp_path / "bin.csv")
    (tmp_path / "empty.csv").write_text("# only a comment\n\n")
    with pytest.raises(InputError, match="empty file") as err:
        read_table(tmp_path / "empty.csv")
    assert err.value.line == 1
