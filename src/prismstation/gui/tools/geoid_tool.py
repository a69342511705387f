"""Tools ▸ Geoid…: choose the geoid that makes orthometric heights ellipsoidal (h = H + N).

A constant undulation (metres), a grid found automatically on PROJ's data paths and
``/usr/share/proj`` (listed), "automatic" (the first grid found, else the constant), or any
other grid file chosen by the operator. A grid that cannot be read is refused with a message
naming the file and the reason; the project is not changed. The choice is one undoable step
(:class:`SetGeoid`), after which the model refits. The active geoid is always shown in the
model panel.
"""
from __future__ import annotations

from pathlib import Path

import shiboken6

from PySide6.QtGui import QUndoCommand
from PySide6.QtWidgets import (QButtonGroup, QDialog, QDialogButtonBox, QDoubleSpinBox, QFileDialog,
                               QGridLayout, QLabel, QLineEdit, QListWidget, QPushButton, QRadioButton,
                               QVBoxLayout)

from prismstation.errors import PrismError
from prismstation.io import geoid as geoid_mod
from prismstation.io.project import project_geoid
from prismstation.io.ranges import UNDULATION_M

GRID_SUFFIXES = (".gtx", ".tif", ".tiff", ".gtx.gz")


class SetGeoid(QUndoCommand):
    """Replace the project's geoid setting (a dict, see :mod:`prismstation.io.geoid`)."""

    def __init__(self, project, setting: dict):
        super().__init__("Change geoid")
        self.project, self.new, self.old = project, dict(setting), dict(project.geoid or {})

    def redo(self) -> None:
        self.project.set_geoid(self.new)

    def undo(self) -> None:
        self.project.set_geoid(self.old)


def found_grids() -> list[Path]:
    """Geoid grids on :func:`prismstation.io.geoid.search_paths`: the known names (EGM96,
    EGM2008) and any ``*egm*`` / ``*geoid*`` grid file, each once, in search order."""
    out: list[Path] = []
    seen = set()
    for d in geoid_mod.search_paths():
        try:
            if not d.is_dir():
                continue
            cands = [d / n for n in geoid_mod.GRID_NAMES]
            cands += sorted(p for p in d.iterdir() if p.is_file()
                            and any(k in p.name.lower() for k in ("egm", "geoid"))
                            and p.name.lower().endswith(GRID_SUFFIXES))
        except OSError:
            continue
        for p in cands:
            if p.is_file() and p.resolve() not in seen:
                seen.add(p.resolve())
                out.append(p)
    return out


def check_setting(setting: dict) -> str | None:
    """None when ``setting`` can be used, else a sentence saying why not (file and reason)."""
    if setting.get("kind") != "grid":
        return None
    path = Path(setting.get("path") or "")
    if not path.is_file():
        return f"The geoid grid {path} does not exist."
    try:
        geoid_mod.GridGeoid(path)
    except PrismError as exc:
        return f"The geoid grid {path} cannot be used: {exc}"
    except Exception as exc:  # a reader failure of another kind: still a message, not a crash
        return f"The geoid grid {path} cannot be read ({type(exc).__name__}: {exc})"
    return None


def describe(project) -> tuple[str, bool]:
    """What the model panel shows for ``project``'s geoid, and whether it is unusable."""
    if project is None:
        return "—", False
    s = project.geoid or {}
    if s.get("kind") == "auto":  # named without reading the grid (the fit reads it)
        g = geoid_mod.find_grid()
        return ("automatic: " + (f"grid {g.name}" if g else
                                 f"constant {float(s.get('value') or 0.0):g} m (no grid found)")), False
    try:
        text = project_geoid(project).describe()
    except PrismError as exc:
        return f"{exc}", True
    except Exception as exc:
        return f"unusable ({type(exc).__name__}: {exc})", True
    return text, False


class GeoidDialog(QDialog):
    """The choice of geoid; :meth:`setting` is the dict to store in the project."""

    def __init__(self, current: dict | None, grids: list[Path], parent=None):
        super().__init__(parent)
        self.setWindowTitle("Geoid")
        current = dict(current or {"kind": "constant", "value": 0.0})
        self.r_const = QRadioButton("Constant undulation")
        self.value = QDoubleSpinBox(decimals=2, minimum=UNDULATION_M[0], maximum=UNDULATION_M[1], suffix=" m")
        self.r_auto = QRadioButton("Automatic (the first grid found, else the constant)")
        self.r_found = QRadioButton("A grid found on this computer")
        self.grids = QListWidget()
        for g in grids:
            self.grids.addItem(str(g))
        if not grids:
            self.grids.addItem("(no geoid grid found on PROJ's paths or /usr/share/proj)")
            self.grids.setEnabled(False)
            self.r_found.setEnabled(False)
        self._grids = list(grids)
        self.r_file = QRadioButton("Another grid file")
        self.file = QLineEdit()
        browse = QPushButton("Browse…")
        browse.clicked.connect(self._browse)
        self.group = QButtonGroup(self)
        for r in (self.r_const, self.r_auto, self.r_found, self.r_file):
            self.group.addButton(r)
        lay = QGridLayout()
        lay.addWidget(self.r_const, 0, 0)
        lay.addWidget(self.value, 0, 1, 1, 2)
        lay.addWidget(self.r_auto, 1, 0, 1, 3)
        lay.addWidget(self.r_found, 2, 0, 1, 3)
        lay.addWidget(self.grids, 3, 0, 1, 3)
        lay.addWidget(self.r_file, 4, 0)
        lay.addWidget(self.file, 4, 1)
        lay.addWidget(browse, 4, 2)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        outer = QVBoxLayout(self)
        outer.addWidget(QLabel("Orthometric heights H become ellipsoidal h = H + N through:"))
        outer.addLayout(lay)
        outer.addWidget(buttons)
        self.grids.itemSelectionChanged.connect(lambda: self.r_found.setChecked(True))
        self.file.textEdited.connect(lambda _: self.r_file.setChecked(True))
        self.value.valueChanged.connect(lambda _: self.r_const.setChecked(True))
        self._show(current)

    def _show(self, s: dict) -> None:
        kind = s.get("kind")
        if s.get("value") is not None:
            self.value.blockSignals(True)
            self.value.setValue(float(s["value"]))
            self.value.blockSignals(False)
        if kind == "auto":
            self.r_auto.setChecked(True)
        elif kind == "grid":
            p = Path(s.get("path", ""))
            hits = [i for i, g in enumerate(self._grids) if g.resolve() == p.resolve()]
            if hits:
                self.grids.setCurrentRow(hits[0])
                self.r_found.setChecked(True)
            else:
                self.file.setText(str(p))
                self.r_file.setChecked(True)
        else:
            self.r_const.setChecked(True)

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Geoid grid", str(Path(self.file.text()).parent),
                                              "Geoid grids (*.gtx *.tif *.tiff);;All files (*)")
        if path:
            self.file.setText(path)
            self.r_file.setChecked(True)

    def setting(self) -> dict:
        if self.r_auto.isChecked():
            return {"kind": "auto", "value": float(self.value.value())}
        if self.r_found.isChecked() and self.grids.currentRow() >= 0 and self._grids:
            return {"kind": "grid", "path": str(self._grids[self.grids.currentRow()].resolve())}
        if self.r_file.isChecked() and self.file.text().strip():
            return {"kind": "grid", "path": str(Path(self.file.text().strip()).expanduser().resolve())}
        return {"kind": "constant", "value": float(self.value.value())}


def apply_geoid(ctx, setting: dict) -> bool:
    """Check ``setting`` and make it the project's geoid as one undo step; an unusable grid is
    a message (the project is not changed). True when the project now uses ``setting``."""
    if ctx.project is None:
        return False
    problem = check_setting(setting)
    if problem:
        ctx.files.warn("Geoid", problem)
        return False
    if dict(setting) != dict(ctx.project.geoid or {}):
        ctx.undo_stack.push(SetGeoid(ctx.project, setting))
    return True


def choose_geoid(ctx, dialog_cls=GeoidDialog) -> bool:
    """The dialog, then :func:`apply_geoid` of the choice; True when the project uses it."""
    if ctx.project is None:
        return False
    dlg = dialog_cls(ctx.project.geoid, found_grids(), ctx.widget)
    if dlg.exec() != QDialog.DialogCode.Accepted:
        return False
    return apply_geoid(ctx, dlg.setting())


def refresh(ctx) -> None:
    panel = ctx.model_panel  # the undo stack can outlive the window's widgets at close
    if panel is None or not shiboken6.isValid(panel):
        return
    text, bad = describe(ctx.project)
    panel.set_geoid(text, bad)


def install(ctx) -> None:
    a = ctx.add_action("&Geoid…", lambda: choose_geoid(ctx),
                       tip="The geoid for orthometric heights: a constant, a grid found, or a grid file")
    ctx.tools_menu.addAction(a)
    ctx.tools["geoid"] = a
    ctx.model_panel.geoid_requested.connect(lambda: choose_geoid(ctx))
    # after the window's own slot has bound the project
    ctx.files.project_opened.connect(lambda _p: refresh(ctx))
    ctx.solver.solution_changed.connect(lambda _s: refresh(ctx))
    ctx.undo_stack.indexChanged.connect(lambda _i: refresh(ctx))
