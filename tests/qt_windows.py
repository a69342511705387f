"""The real main window for GUI tests: built offscreen, and freed at a safe point.

A window freed by a garbage-collector run inside a later event loop can leave a timer event
for its QWindow (offscreen plugin), which crashes Qt — hence the explicit collect on both sides,
of every object (the window freezes the survivors of its full collections: gui/workers.py).
"""


def new_window(qtbot, size=(1500, 950)):
    """A shown, exposed, non-interactive main window with no project."""
    from prismstation.gui.app import make_app
    from prismstation.gui.main_window import MainWindow
    from prismstation.gui.workers import collect_everything

    make_app()
    collect_everything()  # windows left by earlier tests go now (frozen ones too)
    qtbot.wait(1)
    win = MainWindow(interactive=False)
    win.files.interactive = False
    qtbot.addWidget(win)
    win.resize(*size)
    win.show()
    qtbot.waitExposed(win)
    return win


def open_window(qtbot, project_path, size=(1500, 950)):
    """A window on ``project_path``, images loaded and the first fit published."""
    from prismstation.gui.app import wait_settled

    win = new_window(qtbot, size)
    assert win.open_project(project_path, recover=False)
    assert wait_settled(win)
    return win


def close_windows(qtbot, *wins) -> None:
    from prismstation.gui.workers import collect_everything

    for win in wins:
        win.undo_stack.setClean()
        win.close()
        win.deleteLater()
    qtbot.wait(10)
    collect_everything()
