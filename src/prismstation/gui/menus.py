"""The main window's actions, menus and toolbar (built once; the window keeps the actions as
``a_*`` attributes). Tools add their own entries to the Tools menu; :func:`fill_panels_menu`
then lists every dock — the window's and the tools' — under View ▸ Panels."""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QDockWidget, QStyle

from prismstation.gui import settings as st
from prismstation.gui.palette import kind_icon


def act(win, text, slot, shortcut=None, icon=None, tip=None, checkable=False) -> QAction:
    """An action of ``win`` (its shortcut works anywhere in the window)."""
    a = QAction(text, win)
    if isinstance(shortcut, QKeySequence.StandardKey):
        a.setShortcuts(shortcut)
    elif shortcut is not None:
        a.setShortcuts(shortcut if isinstance(shortcut, list) else [QKeySequence(shortcut)])
    if icon is not None:
        a.setIcon(win.style().standardIcon(icon))
    if tip:
        a.setStatusTip(tip)
        a.setToolTip(tip)
    a.setCheckable(checkable)
    if slot is not None:
        a.triggered.connect(slot)
    win.addAction(a)
    return a


def build_actions(win) -> None:
    """The window's ``a_*`` actions (slots are the window's methods; no checked flag passed)."""
    K, S = QKeySequence.StandardKey, QStyle.StandardPixmap
    files, views = win.files, win.views
    win.a_new = act(win, "&New project…", lambda: files.new_project(), K.New, S.SP_FileIcon,
                    "A new project on a scene file")
    win.a_open = act(win, "&Open…", lambda: files.open_project(), K.Open, S.SP_DialogOpenButton,
                     "Open a project")
    win.a_save = act(win, "&Save", lambda: files.save(), K.Save, S.SP_DialogSaveButton,
                     "Save the project")
    win.a_save_as = act(win, "Save &as…", lambda: files.save_as(), K.SaveAs)
    win.a_import = act(win, "&Import points…", lambda: win.import_points(), "Ctrl+I",
                       tip="Ground points or image measurements from a CSV or another tool's file")
    win.a_export = act(win, "&Export report…", lambda: win.export_report(), "Ctrl+E",
                       tip="The fit's report as HTML, PDF, CSV or text")
    win.a_quit = act(win, "&Quit", lambda: win.close(), K.Quit)
    win.a_quit.setShortcutContext(Qt.ShortcutContext.ApplicationShortcut)  # also from a progress dialog
    win.a_undo = win.undo_stack.createUndoAction(win, "&Undo")
    win.a_undo.setShortcuts(K.Undo)
    win.a_undo.setIcon(win.style().standardIcon(S.SP_ArrowBack))
    win.a_redo = win.undo_stack.createRedoAction(win, "&Redo")
    redo_keys = QKeySequence.keyBindings(K.Redo)
    win.a_redo.setShortcuts(redo_keys + [QKeySequence(k) for k in ("Ctrl+Shift+Z", "Ctrl+Y")
                                         if QKeySequence(k) not in redo_keys])
    win.a_redo.setIcon(win.style().standardIcon(S.SP_ArrowForward))
    win.addActions([win.a_undo, win.a_redo])
    win.a_new_point = act(win, "New &point", lambda: win.new_point(), "Insert",
                          S.SP_FileDialogNewFolder, "New tie point: click in each view to place it")
    win.a_del_point = act(win, "&Delete point", lambda: win.delete_point(), "Shift+Del",
                          S.SP_TrashIcon, "Delete the current point and its measurements")
    win.a_del_meas = act(win, "Delete &measurement", lambda: win.delete_measurement(), "Del",
                         tip="Delete the current point's measurement in the view under the cursor")
    win.a_kind = {k: act(win, f"Make {k}", lambda _=False, k=k: win.set_kind(k), f"Ctrl+{i + 1}",
                         tip=f"Make the current point a {k}")
                  for i, k in enumerate(("GCP", "ICP", "TIE"))}
    win.a_zoom_in = act(win, "Zoom &in", lambda: views.zoom_all(1.5),
                        [QKeySequence(K.ZoomIn), QKeySequence("Ctrl+=")], S.SP_ArrowUp, "Zoom in")
    win.a_zoom_out = act(win, "Zoom &out", lambda: views.zoom_all(1 / 1.5), K.ZoomOut,
                         S.SP_ArrowDown, "Zoom out")
    win.a_fit = act(win, "&Fit images", lambda: views.fit_all(), "Ctrl+0", S.SP_TitleBarMaxButton,
                    "Show the whole images")
    win.a_goto = act(win, "&Go to point", lambda: win.drive_to_current(), "Space")
    win.a_next = act(win, "&Next point", lambda: win.step_point(1),
                     [QKeySequence("PgDown"), QKeySequence("Ctrl+Right")], S.SP_MediaSeekForward,
                     "Next point (PgDown)")
    win.a_prev = act(win, "&Previous point", lambda: win.step_point(-1),
                     [QKeySequence("PgUp"), QKeySequence("Ctrl+Left")], S.SP_MediaSeekBackward,
                     "Previous point (PgUp)")
    win.a_dem = act(win, "Reference &DEM…", lambda: win.choose_reference_dem(),
                    tip="Heights for the linked cursor and for points without parallax")
    win.a_linked_nav = act(win, "&Linked navigation", win.linked_nav.set_enabled, checkable=True,
                           tip="Zoom and pan in one view move the others to the same ground")
    win.a_linked_nav.setChecked(True)
    win.a_labels = act(win, "Point &labels", views.set_show_labels, "Ctrl+L", checkable=True)
    win.a_labels.setChecked(st.value(st.Key.SHOW_LABELS))
    win.a_guide = act(win, "&User guide", lambda: win.show_guide(), K.HelpContents,
                      tip="The user guide: a whole job, step by step")
    win.a_about = act(win, "&About", lambda: win.about())


def build_menus(win) -> None:
    """File, Edit, View (with an empty Panels submenu), Tools (filled by the tools), Help."""
    mb = win.menuBar()
    m = win.file_menu = mb.addMenu("&File")
    m.addActions([win.a_new, win.a_open])
    win.recent_menu = m.addMenu("Open &recent")
    m.addSeparator()
    m.addActions([win.a_save, win.a_save_as])
    m.addSeparator()
    m.addActions([win.a_import, win.a_export])
    m.addSeparator()
    m.addAction(win.a_quit)
    m = win.edit_menu = mb.addMenu("&Edit")
    m.addActions([win.a_undo, win.a_redo])
    m.addSeparator()
    m.addActions([win.a_new_point, win.a_del_point, win.a_del_meas])
    m.addSeparator()
    m.addActions(list(win.a_kind.values()))
    m = win.view_menu = mb.addMenu("&View")
    m.addActions([win.a_zoom_in, win.a_zoom_out, win.a_fit, win.a_linked_nav])
    m.addSeparator()
    m.addActions([win.a_goto, win.a_next, win.a_prev, win.a_labels, win.a_dem])
    m.addSeparator()
    win.panels_menu = m.addMenu("&Panels")
    win.panels_menu.aboutToShow.connect(lambda: fill_panels_menu(win))
    win.tools_menu = mb.addMenu("&Tools")  # filled by prismstation.gui.tools modules
    m = mb.addMenu("&Help")
    m.addActions([win.a_guide, win.a_about])


def fill_panels_menu(win) -> None:
    """View ▸ Panels: every dock of the window — its own, then the tools' by title (the window
    fills it once its tools are installed, and again each time the menu opens)."""
    own = [win.docks[k] for k in ("points", "model", "plots", "loupe", "contrast") if k in win.docks]
    others = sorted((d for d in win.findChildren(QDockWidget) if d not in own),
                    key=lambda d: d.windowTitle())
    win.panels_menu.clear()
    win.panels_menu.addActions([d.toggleViewAction() for d in own])
    win.panels_menu.addSeparator()
    win.panels_menu.addActions([d.toggleViewAction() for d in others])


def build_toolbar(win) -> None:
    """One row that fits 1280 px: icons only where there is an icon (the name in its tool tip)."""
    tb = win.addToolBar("Main")
    tb.setObjectName("toolbar_main")
    tb.setMovable(False)
    tb.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonIconOnly)  # kinds have no icon: text
    tb.addActions([win.a_open, win.a_save])
    tb.addSeparator()
    tb.addActions([win.a_undo, win.a_redo])
    tb.addSeparator()
    tb.addActions([win.a_new_point, win.a_del_point])
    for k, a in win.a_kind.items():  # the kind's colour, and its name beside it
        a.setIcon(kind_icon(k))
        tb.addAction(a)
        a.setText(a.text().replace("Make ", ""))
        tb.widgetForAction(a).setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
    tb.addSeparator()
    tb.addActions([win.a_prev, win.a_next])
    tb.addSeparator()
    tb.addActions([win.a_zoom_in, win.a_zoom_out, win.a_fit])
    win.toolbar = tb
