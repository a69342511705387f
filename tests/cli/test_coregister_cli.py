"""The ``coregister`` command: bad input is one clear line, exit 2."""
from prismstation.cli import main


def test_missing_file_is_one_clear_error(tmp_path, capsys):
    assert main(["coregister", str(tmp_path / "nope.tif"), str(tmp_path / "b.tif")]) == 2
    err = capsys.readouterr().err
    assert "nope.tif" in err and "Traceback" not in err

