"""Whatever goes wrong, the command line says it in one line: an unexpected exception names the
command and its file and logs the traceback; Ctrl+C is one line and exit 130; memory running
out, a JSON document nested a hundred thousand deep, a CSV field of 200,000 characters, an RPC
that divides by zero — each one line. ``--version`` starts under a 400 MB address-space limit
(OpenCV is imported at its first use, not at start)."""
from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys

import pytest

from prismstation.cli import main
from tests.robustness import faults as ft
from tests.robustness.hostile import rpc_images


def _env(tmp_path):
    return {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "XDG_STATE_HOME": str(tmp_path / "state")}


@pytest.mark.parametrize("exc, said", [(ZeroDivisionError("a bug"), "unexpected error (ZeroDivisionError: a bug)"),
                                       (MemoryError(), "out of memory")])
def test_an_unexpected_error_is_one_line_and_a_log(sim, tmp_path, monkeypatch, exc, said):
    import prismstation.cli.fit as fit

    def broken(*a, **k):
        raise exc
    monkeypatch.setattr(fit, "stored_solution", broken)
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    rc, out, err = ft.run_cli(["fit", sim / "p.prismproj"])
    lines = err.strip().splitlines()
    assert rc == 1 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"prismstation fit: {sim / 'p.prismproj'}: {said}; details in "), lines[0]
    log = lines[0].rsplit("details in ", 1)[1]
    assert log.startswith(str(tmp_path / "state" / "prismstation"))
    text = open(log).read()
    assert "Traceback" in text and "broken" in text


_SLEEPER = """
import sys, time
import prismstation.cli.fit as fit
from prismstation.cli import main
def slow(args):
    print("started", flush=True)
    time.sleep(30)
fit.run = slow
sys.exit(main(["fit", sys.argv[1]]))
"""


def _interactive():
    """In the child: Ctrl+C as at a terminal. A suite started as a background job of a
    non-interactive shell ignores SIGINT, and a child inherits that (a command run so is right
    to ignore it; this test is about the one at a terminal)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def test_ctrl_c_is_one_line_and_130(sim, tmp_path):
    p = subprocess.Popen([sys.executable, "-c", _SLEEPER, str(sim / "p.prismproj")], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=_env(tmp_path), preexec_fn=_interactive)
    try:
        assert p.stdout.readline().strip() == "started"
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=20)
    finally:
        p.kill()
    assert p.returncode == 130 and err.strip() == "prismstation fit: interrupted", err



_HELPER_SIGNAL = """
import os, signal, time
from prismstation.cli._gdal_lines import GdalLines
from prismstation.io.atomic import FreeSpaceWatch
with GdalLines(), FreeSpaceWatch(os.getcwd()):
    # the main thread blocks SIGINT: the kernel must hand it to another thread of the process
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    os.kill(os.getpid(), signal.SIGINT)
    try:
        t = time.monotonic()
        while time.monotonic() - t < 0.5:   # bytecode: a signal a helper took would raise here
            pass
        print("held", flush=True)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        time.sleep(10)
        print("slept", flush=True)
    except KeyboardInterrupt:
        print("interrupted", flush=True)
"""


def test_a_commands_helper_threads_leave_ctrl_c_to_the_main_thread(tmp_path):
    """A SIGINT the kernel hands to a helper thread (stderr's pump, the free-space sampler)
    leaves a main thread asleep in C asleep: Ctrl+C would wait for its call to return. The
    helpers block it, so it waits for the main thread."""
    r = subprocess.run([sys.executable, "-c", _HELPER_SIGNAL], capture_output=True, text=True, timeout=60,
                       cwd=tmp_path, env=_env(tmp_path), preexec_fn=_interactive)
    assert r.stdout.split() == ["held", "interrupted"], (r.stdout, r.stderr[-800:])

def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (400_000 * 1024, resource.RLIM_INFINITY))


def test_version_starts_under_a_400_mb_limit(tmp_path):
    r = subprocess.run([sys.executable, "-c", "import sys; from prismstation.cli import main; sys.exit(main())", "--version"], capture_output=True, text=True,
                       env=_env(tmp_path), preexec_fn=_limit_memory, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("prismstation "), (r.returncode, r.stderr[-500:])


def test_a_command_out_of_memory_at_start_is_one_line(sim, tmp_path):
    r = subprocess.run([sys.executable, "-c", "import sys; from prismstation.cli import main; sys.exit(main())", "fit", str(sim / "p.prismproj")], capture_output=True,
                       text=True, env=_env(tmp_path), preexec_fn=_limit_memory, timeout=120)
    lines = r.stderr.strip().splitlines()
    assert r.returncode in (0, 1), (r.returncode, r.stderr[-800:])  # never a crash (-11)
    if r.returncode:  # (the stack may fit on another machine: then the fit's answer)
        assert len(lines) == 1 and lines[0].startswith("prismstation fit: ") and "memory" in lines[0], r.stderr


def test_opencv_and_numba_are_not_imported_at_start(tmp_path):
    code = ("import sys; from prismstation.cli import build_parser; build_parser(); "
            "print('cv2' in sys.modules, 'numba' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(tmp_path))
    assert r.stdout.strip() == "False False", r.stderr


def test_a_json_nested_too_deep(tmp_path):
    bad = tmp_path / "deep.prismproj"
    bad.write_text("[" * 100_000)
    line = ft.assert_clean_failure(ft.run_cli(["fit", bad]), "fit", "deep.prismproj")
    assert "nested too deep" in line


def test_a_csv_field_too_long(sim, tmp_path):
    bad = tmp_path / "long.csv"
    bad.write_text('id,E,N,H\n"' + "x" * 200_000 + '",1,2,3\n')
    line = ft.assert_clean_failure(ft.run_cli(["new", tmp_path / "n.prismproj", "--scene", sim / "scene.json",
                                               "--points", bad]), "new", "long.csv")
    assert "line 2" in line


@pytest.mark.parametrize("field, value, said", [("lineDenCoef", None, "line_den is zero"),
                                                 ("latOffset", "95.0", "lat_off = 95")])
def test_an_rpc_that_cannot_be_used(tmp_path, field, value, said):
    """An RPC whose denominator is zero at its centre (it divided by zero in the fit) or whose
    latitude offset is off the Earth: refused when read, in one line."""
    import re
    images = rpc_images(tmp_path / "imgs")
    rpb = images[0].with_suffix(".RPB")
    text = rpb.read_text()
    if value is None:  # the constant term of the line denominator: 0, and the rest too
        new = re.sub(r"lineDenCoef = \((.*?)\);", "lineDenCoef = (" + ",".join(["0.0"] * 20) + ");", text,
                     flags=re.S)
        new = new.replace("lineDenCoef = (0.0,0.0,", "lineDenCoef = (0.0,1e-3,")
    else:
        new = re.sub(rf"{field} = [^;]*;", f"{field} = {value};", text)
    assert new != text
    rpb.write_text(new)
    line = ft.assert_clean_failure(ft.run_cli(["new", tmp_path / "p.prismproj", "--images", *images]), "new",
                                   "img_01")
    assert said in line, line
