"""ImportDialog: column mapping, delimiter guess, CRS, every bad line named, point files."""
from __future__ import annotations

import pytest
from pyproj import Transformer

from prismstation.gui.import_dialog import ImportDialog
from prismstation.io.points import read_ground_points
from prismstation.io.pointfiles import PointFile, write_point_file
from prismstation.model.points import GroundPoint, Measurement

VIEWS = ["N", "F", "B"]


@pytest.fixture
def dialog(qtbot):
    d = ImportDialog(VIEWS, "EPSG:32629")
    qtbot.addWidget(d)
    return d


def ok_enabled(d):
    from PySide6.QtWidgets import QDialogButtonBox
    return d.buttons.button(QDialogButtonBox.StandardButton.Ok).isEnabled()


ROWS = [("A1", 540000.5, 4560000.25, 100.5, "GCP"), ("A2", 540100.0, 4560100.0, 110.0, "ICP"),
        ("A3", 540200.0, 4560250.0, 120.25, "GCP")]


def test_semicolon_file_with_own_names_maps_and_imports(dialog, tmp_path):
    src = tmp_path / "survey.txt"
    src.write_text("# from the field book\nName;Northing;Easting;Elev;Type;Remark\n"
                   + "".join(f"{i};{n};{e};{h};{k};ok\n" for i, e, n, h, k in ROWS))
    dialog.set_path(src)
    assert dialog.delimiter.currentText() == "auto" and "';'" in dialog.format_label.text()
    cols, _ = dialog.mapping()
    assert cols == {"id": "Name", "E": "Easting", "N": "Northing", "H": "Elev", "kind": "Type"}
    assert dialog.errors() == [] and ok_enabled(dialog)
    dialog.height_kind.setCurrentText("orthometric")
    dialog.refresh()
    dialog.accept()
    points, meas = dialog.result()
    # reference: the io reader on the same data in docs/formats.md's own CSV form
    ref = tmp_path / "ref.csv"
    ref.write_text("id,E,N,H,kind\n" + "".join(f"{i},{e},{n},{h},{k}\n" for i, e, n, h, k in ROWS))
    assert points == read_ground_points(ref, height="orthometric") and meas == []
    assert points[0].extra == {"Remark": "ok"} and points[0].height_kind == "orthometric"
    # the preview shows the file's rows under the mapped names, with the file's line numbers
    m = dialog.preview_model
    assert m.columns[:3] == ["id ← Name", "N ← Northing", "E ← Easting"]
    assert m.rows[2][0] == "A3" and m.headerData(0, _vertical()) == "3"


def _vertical():
    from PySide6.QtCore import Qt
    return Qt.Orientation.Vertical


def test_bad_lines_are_all_named_and_block_import(dialog, tmp_path):
    src = tmp_path / "g.csv"
    src.write_text("id,E,N,H\nA1,540000,4560000,100\nA2,540100,4560100,abc\nA3,540200,4560200\n"
                   "A1,540300,4560300,130\nA5,540400,4560400,140\n")
    dialog.set_path(src)
    errs = dialog.errors()
    assert errs == [f"{src}, line 3: column H: 'abc' is not a number",
                    f"{src}, line 4: 3 fields where the header has 4",
                    f"{src}, line 5: point 'A1' appears twice (first on line 2)"]
    assert [dialog.error_list.item(i).text() for i in range(dialog.error_list.count())] == errs
    assert not ok_enabled(dialog) and dialog.result() == ([], [])
    m = dialog.preview_model
    assert sorted(m.problems) == [1, 2, 3]
    from PySide6.QtCore import Qt
    assert m.data(m.index(1, 0), Qt.ItemDataRole.ToolTipRole) == "column H: 'abc' is not a number"
    assert m.data(m.index(0, 0), Qt.ItemDataRole.BackgroundRole) is None


def test_remapping_a_column_and_a_constant_view(dialog, tmp_path):
    src = tmp_path / "m.csv"
    src.write_text("pt\tcol\trow\tcol2\nA1\t10.5\t20.25\t11\nA2\t30\t40\t31\n")
    dialog.set_path(src)
    dialog.what.setCurrentIndex(1)  # measurements
    assert dialog.mapping() == ({"id": "pt", "x": "col", "y": "row"}, {"view": "N"})
    dialog.set_mapping("view", "= F")
    dialog.set_mapping("x", "col2")
    _, meas = dialog.result()
    assert meas == [Measurement("A1", "F", 11.0, 20.25), Measurement("A2", "F", 31.0, 40.0)]
    dialog.set_mapping("x", "(none)")
    assert dialog.errors() == [f"{src}: map a column onto x"] and not ok_enabled(dialog)


def test_measurement_view_not_in_scene(dialog, tmp_path):
    src = tmp_path / "meas.csv"
    src.write_text("id,view,x,y\nA1,N,1,2\nA1,Q,3,4\n")
    dialog.set_path(src)
    assert dialog.what.currentData() == "measurements"
    assert dialog.errors() == [f"{src}, line 3: view 'Q' is not in the scene (views: N, F, B)"]


def test_geographic_source_crs_is_converted(dialog, tmp_path):
    src = tmp_path / "ll.csv"
    src.write_text("id,lon,lat,H,height\nA,-8.5,41.2,100,ellipsoidal\nB,-8.4,41.3,200,\n")
    dialog.set_path(src)
    dialog.crs_edit.setText("not a crs")
    dialog.refresh()
    assert not ok_enabled(dialog) and dialog.errors()[0].startswith("source CRS:")
    dialog.crs_edit.setText("EPSG:4326")
    dialog.refresh()
    assert "WGS 84" in dialog.crs_status.text() and ok_enabled(dialog)
    points, _ = dialog.result()
    tr = Transformer.from_crs("EPSG:4326", "EPSG:32629", always_xy=True)
    e, n = tr.transform(-8.4, 41.3)
    assert points[1].E == pytest.approx(e, abs=1e-6) and points[1].N == pytest.approx(n, abs=1e-6)
    assert [p.height_kind for p in points] == ["ellipsoidal", "ellipsoidal"]


def test_file_without_header(dialog, tmp_path):
    src = tmp_path / "nohead.csv"
    src.write_text("A1 540000 4560000 100\nA2 540100 4560100 x\n")
    dialog.set_path(src)
    dialog.has_header.setChecked(False)
    for f, c in zip(("id", "E", "N", "H"), ("column 1", "column 2", "column 3", "column 4")):
        dialog.set_mapping(f, c)
    assert dialog.errors() == [f"{src}, line 2: column H: 'x' is not a number"]


def test_qgis_points_file_maps_images_to_views(dialog, tmp_path):
    pf = PointFile((GroundPoint("g1", 540000.0, 4560000.0, 0.0), GroundPoint("g2", 541000.0, 4561000.0, 0.0)),
                   (Measurement("g1", "x", 100.25, 200.5), Measurement("g2", "x", 300.0, 400.0)),
                   "EPSG:32629", "qgis")
    path = tmp_path / "ALPSMB012345.points"
    write_point_file(pf, path)
    dialog.set_path(path)
    assert "QGIS" in dialog.format_label.text() and not dialog.delimiter.isEnabled()
    assert dialog.combos["ALPSMB012345"].currentText() == "B"  # PRISM backward-view name
    points, meas = dialog.result()
    assert [p.id for p in points] == ["g1", "g2"] and ok_enabled(dialog)
    assert [(m.id, m.view, m.x, m.y) for m in meas] == [("g1", "B", 100.25, 200.5), ("g2", "B", 300.0, 400.0)]


def test_odm_gcp_list_real_file(dialog, shared_data):
    path = shared_data / "gcp_files" / "odm_data_bellus" / "gcp_list.txt"
    dialog.set_path(path)
    assert "OpenDroneMap" in dialog.format_label.text()
    images = list(dialog.combos)
    assert images and all(c.currentText() == "(none)" for c in dialog.combos.values())
    dialog.combos[images[0]].setCurrentText("N")
    dialog.refresh()
    points, meas = dialog.result()
    assert points and meas and {m.view for m in meas} == {"N"}
    # converted from the file's UTM 17N to the project's UTM 29N
    from prismstation.io.pointfiles import read_point_file
    raw = read_point_file(path)
    tr = Transformer.from_crs("EPSG:32617", "EPSG:32629", always_xy=True)
    assert points[0].E == pytest.approx(tr.transform(raw.points[0].E, raw.points[0].N)[0], abs=1e-6)


def test_content_guessed_from_the_header(dialog, tmp_path):
    src = tmp_path / "obs.tsv"
    src.write_text("pt\tcol\trow\nA1\t10.5\t20.25\n")
    dialog.set_path(src)
    assert dialog.what.currentData() == "measurements" and "'\\t'" in dialog.format_label.text()
    assert dialog.result()[1] == [Measurement("A1", "N", 10.5, 20.25)]
    src = tmp_path / "gp.csv"
    src.write_text("id,x,y,z\nA1,540000,4560000,100\n")
    dialog.set_path(src)
    assert dialog.what.currentData() == "points"
    assert dialog.result()[0] == [GroundPoint("A1", 540000.0, 4560000.0, 100.0)]


def test_reloading_a_fixed_file_keeps_the_mapping(dialog, tmp_path):
    src = tmp_path / "g.csv"
    src.write_text("name,a,b,c,d\nA1,540000,4560000,100,7\nA2,540100,4560100,oops,8\n")
    dialog.set_path(src)
    for f, c in (("E", "a"), ("N", "b"), ("H", "c")):
        dialog.set_mapping(f, c)
    assert dialog.errors() == [f"{src}, line 3: column H: 'oops' is not a number"]
    src.write_text("name,a,b,c,d\nA1,540000,4560000,100,7\nA2,540100,4560100,110,8\n")
    dialog.set_path(src)  # the operator fixed the file and chose it again
    assert dialog.mapping()[0] == {"id": "name", "E": "a", "N": "b", "H": "c"}
    assert dialog.errors() == [] and [p.H for p in dialog.result()[0]] == [100.0, 110.0]


def test_decimal_comma_file(dialog, tmp_path):
    src = tmp_path / "pt.csv"
    src.write_text("Ponto;M;P;Cota\nV1;540000,50;4560000,25;100,5\nV2;540100,00;4560100,00;abc\n",
                   encoding="utf-8")
    dialog.set_path(src)
    assert dialog.decimal_comma.isChecked()
    for f, c in (("id", "Ponto"), ("E", "M"), ("N", "P"), ("H", "Cota")):
        dialog.set_mapping(f, c)
    assert dialog.errors() == [f"{src}, line 3: column H: 'abc' is not a number"]
    src.write_text("Ponto;M;P;Cota\nV1;540000,50;4560000,25;100,5\nV2;540100,00;4560100,00;110\n")
    dialog.set_path(src)
    pts = dialog.result()[0]
    assert [(p.E, p.N, p.H) for p in pts] == [(540000.5, 4560000.25, 100.5), (540100.0, 4560100.0, 110.0)]


def test_odm_file_with_latitude_first_shows_a_warning_and_imports(dialog, shared_data, tmp_path):
    asp = shared_data / "gcp_files" / "asp_StereoPipelineTest" / "ground_control_points.gcp"
    from prismstation.io.pointfiles import read_point_file
    ref = read_point_file(asp).points
    f = tmp_path / "gcp_list.txt"
    f.write_text("WGS84 longlat\n" + "".join(f"{p.N} {p.E} {p.H} 10 20 N.tif {p.id}\n" for p in ref))
    dialog = ImportDialog(VIEWS, "EPSG:3031")  # Antarctic polar stereographic
    dialog.set_path(f)
    assert dialog.errors() == [] and ok_enabled(dialog)
    (w,) = dialog.warnings()
    assert w.startswith("warning: ") and "read geo_x as latitude and geo_y as longitude" in w
    assert dialog.error_list.item(0).text() == w and "1 warning" in dialog.status.text()
    points, meas = dialog.result()
    tr = Transformer.from_crs("EPSG:4326", "EPSG:3031", always_xy=True)
    e, n = tr.transform(ref[0].E, ref[0].N)
    assert points[0].E == pytest.approx(e, abs=1e-6) and points[0].N == pytest.approx(n, abs=1e-6)
    assert {m.view for m in meas} == {"N"}


def test_a_numeric_height_column_is_H_not_the_height_kind(dialog, tmp_path):
    """A survey's "Height" column holds numbers: it is H; the height-kind field stays unmapped."""
    src = tmp_path / "survey.csv"
    src.write_text("Name,Easting,Northing,Height\n"
                   + "".join(f"{i},{e},{n},{h}\n" for i, e, n, h, _ in ROWS))
    dialog.set_path(src)
    cols, _ = dialog.mapping()
    assert cols == {"id": "Name", "E": "Easting", "N": "Northing", "H": "Height"}
    assert dialog.errors() == [] and ok_enabled(dialog)
    assert [p.H for p in dialog.result()[0]] == [100.5, 110.0, 120.25]
    # a column of height kinds named "height" still maps onto the kind field
    src.write_text("id,E,N,H,height\nA1,540000,4560000,100,orthometric\n")
    dialog.set_path(src)
    assert dialog.mapping()[0]["height"] == "height" and dialog.mapping()[0]["H"] == "H"


def test_one_column_feeding_two_fields_is_named_and_blocks(dialog, tmp_path):
    src = tmp_path / "g.csv"
    src.write_text("id,E,N,H\nA1,540000,4560000,100\n")
    dialog.set_path(src)
    assert dialog.errors() == [] and ok_enabled(dialog)
    dialog.set_mapping("N", "E")
    assert dialog.errors() == [f"{src}: column 'E' feeds both E and N: give each field its own column"]
    assert not ok_enabled(dialog)
    dialog.set_mapping("N", "N")
    assert dialog.errors() == [] and ok_enabled(dialog)
