"""Column-mapped CSV reading (no Qt): guesses and every bad line named."""
import pytest

from prismstation.io.csvtable import guess_delimiter
from prismstation.io.mapped_csv import GROUND_FIELDS, guess_mapping, read_mapped


def test_pure_helpers():
    assert guess_delimiter(["a;b;c", "1;2,5;3"]) == ";"
    assert guess_delimiter(["a b c", "1 2 3"]) == " "
    assert guess_delimiter(["a\tb", "1\t2"]) == "\t"
    m = guess_mapping(["Point", "X", "Y", "Z", "height"], GROUND_FIELDS)
    assert m == {"id": "Point", "E": "X", "N": "Y", "H": "Z", "height": "height"}


def test_every_bad_line_is_read_without_a_temporary_file(tmp_path, monkeypatch):
    import tempfile
    monkeypatch.setattr(tempfile, "mkstemp", lambda *a, **k: pytest.fail("temporary file"))
    text = "".join(f"P{i},{i},x,1\n" for i in range(1, 301))
    recs, errs = read_mapped(tmp_path / "g.csv", "points", "id,E,N,H\n" + text,
                             {"id": "id", "E": "E", "N": "N", "H": "H"})
    assert recs == [] and len(errs) == 200 and errs[-1].line == 201
    assert str(errs[0]) == f"{tmp_path / 'g.csv'}, line 2: column N: 'x' is not a number"
