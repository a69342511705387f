"""File ▸ Import…, File ▸ Export report… and File ▸ Report operator… of the main window.

The import dialog (:mod:`prismstation.gui.import_dialog`) and the HTML/PDF writer
(:mod:`prismstation.gui.report_writer`) are imported lazily; where a build lacks them the
window says so instead of failing. An import is one undoable step; CSV and JSON reports go
through :func:`prismstation.io.report.write_report`. The export's file dialog opens in the
project's folder with a name proposed (``<project>_report.pdf``); the operator named on reports
is asked the first time only and remembered (File ▸ Report operator… changes it).
"""
from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QInputDialog, QMessageBox

from prismstation.errors import PrismError
from prismstation.gui import commands as cmd, settings as st
from prismstation.gui.import_dialog import ImportDialog
from prismstation.gui.report_writer import write_document
from prismstation.io.report import default_operator, write_report
from prismstation.ops.fit import project_report
from prismstation.gui.plain import plain

REPORT_FILTER = "HTML (*.html);;PDF (*.pdf);;CSV (*.csv);;JSON (*.json)"


def import_points(window) -> None:
    """Run the import dialog on the window's project and push what it read."""
    if window.project is None:
        return
    dlg = ImportDialog(list(window.project.scene.views), window.project.scene.crs, window,
                       height_kind=window.project.height_kind())
    if dlg.exec():
        points, ms = dlg.result()
        push_import(window, points, ms)


def push_import(window, points, ms) -> None:
    """Add imported points and measurements to the window's project as one undoable step."""
    points, ms = list(points or []), list(ms or [])
    if window.project is not None and (points or ms):
        window.undo_stack.push(cmd.Import(window.project, points, ms,
                                          f"Import {len(points)} points, {len(ms)} measurements"))


def report_operator(window, ask: bool) -> str | None:
    """The operator named on a report: the name given once (remembered), else the login name;
    with ``ask``, offered for editing first (``None``: the operator cancelled)."""
    name = st.value(st.Key.REPORT_OPERATOR) or default_operator()
    if ask:
        name, ok = QInputDialog.getText(window, "Report operator", "Operator named on reports:",
                                        text=name)
        if not ok:
            return None
        name = name.strip() or default_operator()
        st.set_value(st.Key.REPORT_OPERATOR, name)
        window.statusBar().showMessage(f"Reports will name {name} as the operator", 8000)
    return name


def proposed_report_path(window) -> str:
    """Where the export's file dialog starts: the folder of the last report exported (while it
    exists), else the project's, else the home folder; ``<project>_report.pdf``."""
    path = window.files.path
    last = st.value(st.Key.LAST_EXPORT_DIR)
    folder = (Path(last) if last and Path(last).is_dir() else Path(path).parent if path else Path.home())
    return str(folder / f"{Path(path).stem if path else 'untitled'}_report.pdf")


def export_report(window, path: str | None = None) -> bool:
    """Write the current Solution's report (:func:`prismstation.ops.fit.project_report`, the
    content ``prismstation report`` writes): HTML or PDF (report writer), CSV or JSON. Without
    ``path``, asks for the file and the operator's name; says on the status bar what it wrote."""
    sol = window.solver.solution
    if sol is not None and window.project is not None and sol.revision != window.project.revision:
        sol = window.solver.refit_now()  # the report lists the points as they are now
    if sol is None or window.project is None or sol.revision != window.project.revision:
        window.statusBar().showMessage("No fit of the current points to report (see the model panel)", 8000)
        return False
    ask = path is None
    if ask:
        path, _ = QFileDialog.getSaveFileName(window, "Export report", proposed_report_path(window),
                                              REPORT_FILTER, "PDF (*.pdf)")
        if not path:
            return False
    operator = report_operator(window, ask and not st.value(st.Key.REPORT_OPERATOR))
    if operator is None:
        return False
    try:
        rep = project_report(window.project, sol, window.files.path, operator=operator)
        if Path(path).suffix.lower() in (".html", ".htm", ".pdf"):
            write_document(rep, path)
        else:
            write_report(rep, path)
    except (PrismError, OSError) as exc:
        QMessageBox.warning(window, "Export report", plain(str(exc)))
        return False
    st.set_value(st.Key.LAST_EXPORT_DIR, str(Path(path).parent))
    window.statusBar().showMessage(f"Report written to {path} (operator {operator}: File ▸ Report "
                                   "operator… changes it)", 8000)
    return True
