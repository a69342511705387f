"""A real X desktop for tests: Xvfb with the openbox window manager, and the workstation
started on it as a user starts it (``prismstation gui PROJECT``, ``QT_QPA_PLATFORM=xcb``),
driven by xdotool and wmctrl. Offscreen hides what a real desktop does (window-manager
maximize, deferred layouts, frames); these helpers let a test see it."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TOOLS = ("Xvfb", "openbox", "xdotool", "wmctrl", "xprop", "xwininfo")


def missing_tools() -> list[str]:
    return [t for t in TOOLS if shutil.which(t) is None]


class Desktop:
    """An X server of ``width`` × ``height`` with a window manager; ``env`` for its clients."""

    _started = 0  # desktops this process has started: each gets a display number of its own

    def __init__(self, width: int, height: int):
        self._xvfb_log = tempfile.TemporaryFile()
        for _ in range(20):
            num = self._next_display()
            r, w = os.pipe()
            self._xvfb_log.seek(0)
            self._xvfb_log.truncate()
            # -noreset: an X server resets when its last client leaves, and refuses clients
            # meanwhile; the window manager's check (wmctrl) could be that client on a busy
            # machine, before openbox had connected: "openbox: Failed to open the display"
            # (2 desktops in 160 beside the GUI suite; a client leaving over and over while
            # openbox starts: 4 in 130, 0 in 130 with -noreset)
            self.xvfb = subprocess.Popen(["Xvfb", f":{num}", "-displayfd", str(w), "-screen", "0",
                                          f"{width}x{height}x24", "-nolisten", "tcp", "-noreset"],
                                         pass_fds=(w,), stderr=self._xvfb_log)
            os.close(w)
            with os.fdopen(r) as f:
                ready = f.readline().strip()     # written once the server accepts clients
            if ready:
                break
            self.xvfb.wait()                      # that display was taken: the next one
        else:
            raise RuntimeError("Xvfb did not start")
        self.env = {**os.environ, "DISPLAY": f":{num}", "QT_QPA_PLATFORM": "xcb"}
        self._wm_log = tempfile.TemporaryFile()
        self.wm = subprocess.Popen(["openbox"], env=self.env, stdout=self._wm_log, stderr=subprocess.STDOUT)
        try:
            self.wait(self._wm_up, 10, "openbox")
        except AssertionError:
            xvfb_exit = self.xvfb.poll()
            log, xlog = self._log(self._wm_log), self._log(self._xvfb_log)
            self.close()
            raise AssertionError(f"openbox on {self.env['DISPLAY']} not up after 10 s (exit "
                                 f"{self.wm.returncode}): {log or 'no output'}; Xvfb "
                                 f"{'running' if xvfb_exit is None else f'exited with {xvfb_exit}'}, "
                                 f"it said: {xlog[-2000:] or 'nothing'}") from None

    @staticmethod
    def _log(f) -> str:
        f.seek(0)
        return f.read().decode(errors="replace").strip()

    def _wm_up(self) -> bool:
        """The window manager answers (it is not up if it has exited)."""
        if self.wm.poll() is not None:
            raise AssertionError("exited")
        return self.run("wmctrl", "-m", check=False).returncode == 0

    @classmethod
    def _next_display(cls) -> int:
        """A display number no other test worker uses and this one has not used lately. Xvfb's
        own choice (the lowest free) reuses the number another worker's server is just giving
        up, and openbox then could not connect ("Failed to open the display": in 3 of 4 runs of
        the GUI tests with 4 workers, 0 of 5 with a display per worker) — most likely the exiting
        server removing the socket the new one had made."""
        worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0").lstrip("gw")
        base = 400 + 100 * (int(worker) if worker.isdigit() else 0)
        while True:
            num = base + cls._started % 100
            cls._started += 1
            if not Path(f"/tmp/.X{num}-lock").exists():
                return num

    def run(self, *cmd, check=True) -> subprocess.CompletedProcess:
        r = subprocess.run(cmd, env=self.env, capture_output=True, text=True, timeout=30)
        if check and r.returncode:
            raise AssertionError(f"{' '.join(cmd)} exited with {r.returncode}: {r.stderr.strip()}")
        return r

    def screenshot(self) -> "np.ndarray":
        """The screen as the X server has it now, ``(height, width, 3)`` RGB (taken by a Qt client
        of this display: the pixels the windows put there, not a fresh render of them)."""
        import numpy as np
        code = ("import sys\n"
                "from PySide6.QtGui import QGuiApplication, QImage\n"
                "app = QGuiApplication([])\n"
                "im = app.primaryScreen().grabWindow(0).toImage().convertToFormat(QImage.Format.Format_RGB888)\n"
                "w, h, bpl = im.width(), im.height(), im.bytesPerLine()\n"
                "raw = bytes(im.constBits())\n"
                "sys.stdout.buffer.write(b'%d %d\\n' % (w, h))\n"
                "sys.stdout.buffer.write(b''.join(raw[y * bpl:y * bpl + 3 * w] for y in range(h)))\n")
        r = subprocess.run([sys.executable, "-c", code], env=self.env, capture_output=True, timeout=30)
        if r.returncode:
            raise AssertionError(f"screenshot failed: {r.stderr.decode(errors='replace')[-500:]}")
        head, data = r.stdout.split(b"\n", 1)
        w, h = map(int, head.split())
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)

    @staticmethod
    def wait(cond, seconds: float, what: str):
        t = time.monotonic() + seconds
        while time.monotonic() < t:
            v = cond()
            if v:
                return v
            time.sleep(0.1)
        raise AssertionError(f"timed out waiting for {what}")

    def close(self) -> None:
        for p in (self.wm, self.xvfb):
            p.terminate()
            try:
                p.wait(5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        self._wm_log.close()
        self._xvfb_log.close()


class App:
    """``prismstation gui PROJECT`` on ``desktop`` with its settings in ``settings_dir``."""

    def __init__(self, desktop: Desktop, project: Path, settings_dir: Path):
        self.d = desktop
        env = {**desktop.env, "PRISMSTATION_SETTINGS_DIR": str(settings_dir), "PYTHONFAULTHANDLER": "1"}
        exe = Path(sys.executable).with_name("prismstation")  # the command the README gives
        self.proc = subprocess.Popen([str(exe), "gui", str(project)],
                                     env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.wid = desktop.wait(self._window, 60, "the main window")

    def _window(self) -> str | None:
        if self.proc.poll() is not None:
            raise AssertionError(f"the workstation exited with {self.proc.returncode} before its "
                                 f"window showed:\n{self.proc.stdout.read()}")
        r = self.d.run("xdotool", "search", "--all", "--onlyvisible", "--pid", str(self.proc.pid),
                       "--name", "prismstation", check=False)
        ids = r.stdout.split()
        return ids[0] if ids else None

    def geometry(self) -> tuple[int, int, int, int]:
        """The window's client area (x, y, width, height) on the screen."""
        out = self.d.run("xwininfo", "-id", self.wid).stdout  # (xdotool adds the frame twice)
        g = dict(line.strip().split(":", 1) for line in out.splitlines() if line.count(":") == 1)
        return tuple(int(g[k]) for k in ("Absolute upper-left X", "Absolute upper-left Y", "Width", "Height"))

    def maximized(self) -> bool:
        out = self.d.run("xprop", "-id", self.wid, "_NET_WM_STATE").stdout
        return "_NET_WM_STATE_MAXIMIZED_VERT" in out and "_NET_WM_STATE_MAXIMIZED_HORZ" in out

    def maximize(self) -> None:
        """What the title bar's maximize button asks of the window manager."""
        self.d.run("wmctrl", "-i", "-r", self.wid, "-b", "add,maximized_vert,maximized_horz")
        self.d.wait(self.maximized, 10, "the window to be maximized")

    def alive_for(self, seconds: float) -> bool:
        try:
            self.proc.wait(seconds)
        except subprocess.TimeoutExpired:
            return True
        return False

    def quit(self) -> tuple[int, str]:
        """Ctrl+Q in the window; the exit status and everything the process printed."""
        self.wid = self.d.wait(self._window, 10, "the main window")
        self.d.run("xdotool", "windowactivate", "--sync", self.wid)
        self.d.run("xdotool", "key", "ctrl+q")  # real key events (XTEST), to the active window
        try:
            self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise AssertionError("Ctrl+Q did not quit the workstation") from None
        return self.proc.returncode, self.proc.stdout.read()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
