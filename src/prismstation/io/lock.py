"""``<project>.lock``: which process works on a project — the one lock the window and the
command line honour.

The window takes the lock of the project it has open (and its crash-recovery journal is that
process's); a second window does not open a project another one holds, and a command that
writes a project (:func:`prismstation.io.project.save_project`: ``new --force``,
``orient-dem --save``) refuses one another process holds (:func:`refuse_if_held`). Commands
that only read a project do not look at the lock.
"""
from __future__ import annotations

import json
import logging
import os
import socket
import time
from pathlib import Path

from prismstation.errors import InputError
from prismstation.io import atomic
from prismstation.io.jsonfile import dumps

_log = logging.getLogger(__name__)
LOCK_SUFFIX = ".lock"


def lock_path(project_path) -> Path:
    p = Path(project_path)
    return p.with_name(p.name + LOCK_SUFFIX)


def _process_start(pid: int) -> str | None:
    """The start time of process ``pid`` as the kernel counts it (Linux), None elsewhere or
    when there is no such process: with the pid, it names one process even after pid reuse."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[-1].split()[19]  # field 22, counted after the command name


def _alive(pid: int, start: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: it exists
        pass
    except OSError:
        return False
    now = _process_start(pid)
    return start is None or now is None or now == start


class ProjectLock:
    """``<project>.lock``: which process works on a project (its journal is that process's).

    The file holds ``{"pid", "host", "start", "since"}`` (``start``: the process's start time
    on Linux, against pid reuse; ``since``: seconds since the epoch). :meth:`holder` is the
    other live process holding it, or None: a lock of this process, or of a process of this
    host that no longer runs (a crash, ``kill -9``: stale, removed) does not count. A lock
    from another host cannot be checked: it counts, with its ``host`` and ``since`` to judge by.
    """

    def __init__(self, project_path):
        self.path = lock_path(project_path)
        self.held = False

    @staticmethod
    def _me() -> dict:
        return {"pid": os.getpid(), "host": socket.gethostname(), "start": _process_start(os.getpid())}

    def holder(self) -> dict | None:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            pid, host = int(data["pid"]), str(data["host"])
        except FileNotFoundError:
            return None
        except (OSError, ValueError, KeyError, TypeError):  # half written, not ours: stale
            self._remove()
            return None
        me = self._me()
        if host == me["host"] and (pid == me["pid"] or not _alive(pid, data.get("start"))):
            if pid != me["pid"]:
                self._remove()
            return None
        return data

    def acquire(self) -> None:
        """Write this process's lock (atomically); a failure to write is not an error (a
        read-only folder): the project then opens unlocked."""
        try:
            atomic.write_atomic(self.path, dumps({**self._me(), "since": time.time()}), keep_backup=False)
            self.held = True
        except OSError as exc:
            _log.warning("project lock %s not written: %s", self.path, exc)

    def release(self) -> None:
        if self.held:
            self.held = False
            try:
                data = json.loads(self.path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return
            if data.get("pid") == os.getpid() and data.get("host") == socket.gethostname():
                self._remove()

    def _remove(self) -> None:
        try:
            os.unlink(self.path)
        except OSError:
            pass


def describe_holder(holder: dict) -> str:
    """``process 1234 on host, since 17:02`` for a message."""
    since = holder.get("since")
    when = time.strftime("%Y-%m-%d %H:%M", time.localtime(since)) if isinstance(since, (int, float)) else "?"
    return f"process {holder.get('pid')} on {holder.get('host')}, since {when}"


def refuse_if_held(project_path) -> None:
    """An :class:`InputError` naming ``project_path`` when another live process (a window)
    holds its lock: what is written here would be lost at that window's next save."""
    holder = ProjectLock(project_path).holder()
    if holder is not None:
        raise InputError(f"open in prismstation ({describe_holder(holder)}): close it there before "
                         "writing it from here (its next save would drop this change)", project_path)
