"""A tool's job and a second window on a real X server with a window manager (Xvfb + openbox),
the workstation started as a user starts it and driven by keys and the window manager:

- a job started from the Tools menu, its progress dialog closed by the window manager (the
  title bar's X), then Ctrl+Q — once a crash at quit (``QObject: shared QObject was deleted
  directly``, ``malloc_consolidate(): unaligned fastbin chunk``);
- X or Ctrl+Q while the job runs asks whether to cancel it and quit;
- a second instance opening the same project is refused with the reason, and never offers to
  "recover" the first one's journal."""
from __future__ import annotations

import json
import sys

import pytest

from tests.gui.sim_project import copy_sim, make_sim
from tests.gui.xdesktop import App, Desktop, missing_tools

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="an X server is Linux-only")

TROUBLE = ("QObject:", "malloc", "Fatal Python error", "Segmentation", "Traceback", "double free")


@pytest.fixture()
def desktop():
    if missing_tools():  # packaging/setup.sh --test installs them
        pytest.fail(f"missing for the real-desktop tests: {', '.join(missing_tools())}")
    d = Desktop(1600, 1000)
    yield d
    d.close()


@pytest.fixture(scope="module")
def sim_master(tmp_path_factory):
    return make_sim(tmp_path_factory.mktemp("xsim"))


@pytest.fixture()
def project(sim_master, tmp_path):
    """The simulated project with its reference DEM recorded (the dialog offers it)."""
    d = copy_sim(sim_master, tmp_path / "sim")
    doc = json.loads((d / "p.prismproj").read_text())
    doc.update({"format": "prismstation-project/2", "reference_dem": "srtm.tif"})
    (d / "p.prismproj").write_text(json.dumps(doc))
    return d / "p.prismproj"


def windows_named(desktop, app, name) -> list[str]:
    """Ids of ``app``'s visible windows titled ``name``."""
    r = desktop.run("xdotool", "search", "--all", "--onlyvisible", "--pid", str(app.proc.pid), "--name",
                    f"^{name}$", check=False)
    return r.stdout.split()


def window_named(desktop, app, name, seconds=30):
    """The id of ``app``'s visible window titled ``name``."""
    return desktop.wait(lambda: (windows_named(desktop, app, name) or [None])[-1], seconds,
                        f"a window titled {name!r}")


def gone(desktop, app, name) -> bool:
    return not windows_named(desktop, app, name)


def start_orientation(desktop, app):
    """Tools ▸ Orient from reference DEM… by keys (Alt+T, the item under the first), OK."""
    desktop.run("xdotool", "windowactivate", "--sync", app.wid)
    desktop.run("xdotool", "key", "alt+t")
    desktop.run("xdotool", "key", "Down")
    desktop.run("xdotool", "key", "Return")
    dlg = window_named(desktop, app, "Orient from reference DEM")
    desktop.run("xdotool", "windowactivate", "--sync", dlg)
    desktop.run("xdotool", "key", "Return")
    return window_named(desktop, app, "Orientation from the reference DEM")


def test_a_job_its_progress_dialog_closed_then_quit(desktop, project, tmp_path):
    for _ in range(2):
        app = App(desktop, project, tmp_path / "s")
        try:
            progress = start_orientation(desktop, app)
            desktop.run("wmctrl", "-i", "-c", progress)          # the title bar's X, through the WM
            desktop.wait(lambda: gone(desktop, app, "Orientation from the reference DEM"), 10,
                         "the progress dialog to close")
            rc, out = app.quit()
            assert rc == 0 and not any(t in out for t in TROUBLE), out
        finally:
            app.kill()


def test_x_and_ctrl_q_while_a_job_runs_ask_first(desktop, project, tmp_path):
    app = App(desktop, project, tmp_path / "s")
    try:
        start_orientation(desktop, app)
        desktop.run("wmctrl", "-i", "-c", app.wid)                 # the main window's X
        box = window_named(desktop, app, "Quit", 10)
        desktop.run("xdotool", "windowactivate", "--sync", box)
        desktop.run("xdotool", "key", "Escape")                    # No: the job goes on
        desktop.wait(lambda: gone(desktop, app, "Quit"), 10, "the question to close")
        assert app.alive_for(1) and not gone(desktop, app, "Orientation from the reference DEM")
        desktop.run("xdotool", "windowactivate", "--sync", app.wid)
        desktop.run("xdotool", "key", "ctrl+q")
        box = window_named(desktop, app, "Quit", 10)
        desktop.run("xdotool", "windowactivate", "--sync", box)
        desktop.run("xdotool", "key", "alt+y")                     # Yes (to Ctrl+Q): cancel it and quit
        app.proc.wait(60)
        out = app.proc.stdout.read()
        assert app.proc.returncode == 0 and not any(t in out for t in TROUBLE), out
    finally:
        app.kill()


def test_a_second_instance_does_not_recover_the_first_ones_journal(desktop, project, tmp_path):
    first = App(desktop, project, tmp_path / "s1")
    second = None
    try:
        desktop.run("xdotool", "windowactivate", "--sync", first.wid)
        desktop.run("xdotool", "key", "Insert")                    # an unsaved edit: journaled
        desktop.wait(lambda: (project.parent / "p.prismproj.recovery").exists(), 10, "the journal")
        second = App(desktop, project, tmp_path / "s2")
        box = window_named(desktop, second, "Open project", 30)
        assert gone(desktop, second, "Recover")
        name = desktop.run("xdotool", "getwindowname", box).stdout.strip()
        assert name == "Open project"
        desktop.run("xdotool", "windowactivate", "--sync", box)
        desktop.run("xdotool", "key", "Return")
        desktop.wait(lambda: gone(desktop, second, "Open project"), 10, "the message to close")
        assert gone(desktop, second, "Recover")
        rc, out = second.quit()
        assert rc == 0 and not any(t in out for t in TROUBLE), out
        assert (project.parent / "p.prismproj.recovery").exists()   # the first one's, untouched
    finally:
        for a in (second, first):
            if a is not None:
                a.kill()



def start_dsm(desktop, app):
    """Tools ▸ Export DSM… by keys (Alt+T, the third item: the second, Back to GCP orientation, is
    disabled), OK with the dialog's defaults."""
    desktop.run("xdotool", "windowactivate", "--sync", app.wid)
    desktop.run("xdotool", "key", "alt+t")
    desktop.run("xdotool", "key", "Down")
    desktop.run("xdotool", "key", "Down")
    desktop.run("xdotool", "key", "Return")
    dlg = window_named(desktop, app, "Export DSM")
    desktop.run("xdotool", "windowactivate", "--sync", dlg)
    desktop.run("xdotool", "key", "Return")
    return window_named(desktop, app, "DSM")


def test_the_quit_question_closes_when_the_job_ends(desktop, project, tmp_path):
    """Ctrl+Q while the DSM is made, the question left open: when the job ends the question
    goes (it said a job ran under the job's own "Wrote …" box), the window stays and shows the
    outcome; then Ctrl+Q quits without a question."""
    before = set(project.parent.glob("*.tif"))
    app = App(desktop, project, tmp_path / "s")
    try:
        start_dsm(desktop, app)
        desktop.run("xdotool", "windowactivate", "--sync", app.wid)
        desktop.run("xdotool", "key", "ctrl+q")
        window_named(desktop, app, "Quit", 10)
        desktop.wait(lambda: gone(desktop, app, "Quit"), 120, "the question to go when the job ends")
        assert app.alive_for(0.5)
        done = window_named(desktop, app, "DSM", 10)              # "Wrote …": the outcome
        assert gone(desktop, app, "Quit")
        desktop.run("xdotool", "windowactivate", "--sync", done)
        desktop.run("xdotool", "key", "Return")
        desktop.wait(lambda: gone(desktop, app, "DSM"), 10, "the outcome to be read")
        rc, out = app.quit()                                        # no job: no question
        assert rc == 0 and not any(t in out for t in TROUBLE), out
        assert len(set(project.parent.glob("*.tif")) - before) == 1  # the DSM
    finally:
        app.kill()
