"""The main window's layout: dock sizes for a first start, the start page in and out, and
scroll areas that keep panels from growing the window.

Functions of the window (``win``: a :class:`~prismstation.gui.main_window.MainWindow`).
"""
from __future__ import annotations

from PySide6.QtCore import QRect, Qt, QTimer
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QScrollArea, QTabBar

from prismstation.gui.text_label import TextLabel


def scrolled(widget) -> QScrollArea:
    """``widget`` in a frameless scroll area: a dock's content then asks for little room, and
    showing more panels than the screen holds scrolls them instead of growing the window
    past the screen (the tools' panels have tables and forms hundreds of pixels tall)."""
    sa = QScrollArea()
    sa.setWidgetResizable(True)
    sa.setFrameShape(QScrollArea.Shape.NoFrame)
    sa.setWidget(widget)
    return sa


# what a window manager adds around the window (title bar, borders), for a first size
FRAME_W, FRAME_H = 16, 48


def restore(win, geometry, state) -> None:
    """Lay out a new window: the saved dock ``state`` (else :func:`default_layout`), the start
    page, then the saved ``geometry`` when it fits the screen (else :func:`fit_to_screen`).

    The order matters. Qt defers the dock state of a window that is maximized but not yet
    shown to its first resize; restored after a maximized geometry, that deferred state
    still names the docks the start page then takes out of the layout, and the first
    ``show()`` crashes in ``QLayout::activate`` (on a real X server, not offscreen). So the
    state is restored while the window is still a plain, unshown one, and the geometry —
    maximized or not — last."""
    fit_to_screen(win)
    if state is not None and not state.isEmpty() and win.restoreState(state):
        pass
    else:
        default_layout(win)
    show_start(win, True)
    if geometry is None or geometry.isEmpty() or not win.restoreGeometry(geometry):
        return
    a, n = available(win), win.normalGeometry()
    if n.width() > a.width() - FRAME_W or n.height() > a.height() - FRAME_H or not a.intersects(n):
        maximized = win.isMaximized()  # saved on a larger screen: keep only "maximized"
        win.setWindowState(Qt.WindowState.WindowNoState)
        fit_to_screen(win)
        if maximized:
            win.setWindowState(Qt.WindowState.WindowMaximized)


def available(win) -> QRect:
    """The available geometry (screen less panels) of the screen ``win`` is on."""
    screen = win.screen() or QGuiApplication.primaryScreen()
    return screen.availableGeometry()


def fit_to_screen(win) -> None:
    """A first size: 1,600 × 1,000 px, or 80 % of a larger screen, never more than the
    available area less the window manager's frame; centred on the screen."""
    a = available(win)
    w = min(max(1600, int(a.width() * 0.8)), a.width() - FRAME_W)
    h = min(max(1000, int(a.height() * 0.8)), a.height() - FRAME_H)
    win.setGeometry(a.x() + (a.width() - w) // 2, a.y() + (a.height() - h + FRAME_H) // 2, w, h)


def default_layout(win) -> None:
    """Dock sizes for a first start at ``win``'s size: images large, table and plots below,
    model panel and loupes at right (measured: 7.5 model lines at 1280 × 720, 17 at 1920 × 1080)."""
    d = win.docks
    w, h = win.width(), win.height()
    bottom = int(h * (0.3 if h < 900 else 0.36))
    # the right column: what menus, toolbar, status bar and the bottom docks leave
    right = h - bottom - win.menuBar().sizeHint().height() - win.toolbar.sizeHint().height() \
        - win.statusBar().sizeHint().height() - 12
    side = max(int(w * 0.24), 330)
    # three square loupes side by side (no taller than wide), at most 12 % of the height;
    # 50 px for the dock's title and tabs; the model panel gets the rest
    loupe = min((side - 16) // 3, int(h * 0.12)) + 50
    win.resizeDocks([d["model"], d["loupe"]], [right - loupe, loupe], Qt.Orientation.Vertical)
    win.resizeDocks([d["model"]], [side], Qt.Orientation.Horizontal)
    win.resizeDocks([d["points"], d["plots"]], [int(w * 0.42), int(w * 0.58)], Qt.Orientation.Horizontal)
    win.resizeDocks([d["points"]], [bottom], Qt.Orientation.Vertical)


# a tool's panel opened alone in an area joins the window's own group there
TAB_GROUPS = {Qt.DockWidgetArea.RightDockWidgetArea: "loupe",
              Qt.DockWidgetArea.BottomDockWidgetArea: "points"}


def tab_when_shown(win, dock) -> None:
    """When ``dock`` (a tool's panel) is shown alone in the right or bottom area, tab it with
    the loupes or the point table there: opened as a split of its own it took the model
    panel's height (down to one line at 1600 × 1000). A dock the operator placed elsewhere, or
    already tabbed, stays where it is."""
    def shown(visible: bool) -> None:
        area = win.dockWidgetArea(dock)
        group = win.docks.get(TAB_GROUPS.get(area, ""))
        if (not visible or dock.isFloating() or group is None or group is dock
                or win.tabifiedDockWidgets(dock) or win._work_state is not None):
            return
        win.tabifyDockWidget(group, dock)
        QTimer.singleShot(0, win, dock.raise_)  # in front, once the tab exists
    dock.visibilityChanged.connect(shown)


def show_start(win, on: bool) -> None:
    """The start page (no project: panels and toolbar away, their layout kept) or the
    work area. Docks are taken out of the layout, not hidden: a hidden tab group leaves a
    stray tab bar."""
    if on and win._work_state is None:
        win._work_state = win.saveState()
        for d in win.docks.values():
            win.removeDockWidget(d)
        for bar in win.findChildren(QTabBar, options=Qt.FindChildOption.FindDirectChildrenOnly):
            bar.hide()  # the layout shows the ones it uses again
    elif not on and win._work_state is not None:
        win.restoreState(win._work_state)
        win._work_state = None
        for ms in (0, 200):  # after the layout passes the restore starts
            QTimer.singleShot(ms, win, lambda: hide_stray_tab_bars(win))
    win.toolbar.setVisible(not on)
    for lab in win.statusBar().findChildren(TextLabel):  # coordinates of no image
        lab.setVisible(not on)
    win.central.setCurrentWidget(win.start_page if on else win.central.widget(1))
    win.start_page.set_demo_available(win.demo_maker is not None)


def hide_stray_tab_bars(win) -> None:
    """Hide the dock tab bars Qt leaves visible outside the dock areas after ``restoreState``
    (the start page going away): with one tab, or a copy of a live group's, drawn at the
    window's top-left corner over the menu bar. A live bar sits below the menu bar and holds
    two tabs or more. Called once per restore, deferred (not from an event filter: Qt shows
    some of these bars again on its next layout pass, and fighting it repaints forever)."""
    top = win.menuBar().geometry().bottom()
    area = win.rect().adjusted(0, top + 1, 0, 0)
    for bar in win.findChildren(QTabBar, options=Qt.FindChildOption.FindDirectChildrenOnly):
        if bar.isVisible() and bar.geometry().intersects(win.rect()) and (
                bar.count() < 2 or not area.contains(bar.geometry())):
            bar.hide()
