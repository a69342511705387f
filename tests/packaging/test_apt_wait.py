"""packaging/apt_wait.sh: the set-up waits for another apt's locks instead of failing at once."""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
APT_WAIT = ROOT / "packaging" / "apt_wait.sh"


def _run(cmd: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", f". {APT_WAIT} && {cmd}"], env=env, capture_output=True,
                          text=True, timeout=60)


def _fake_apt(tmp_path: Path, lock_failures: int, other_error: bool = False) -> dict:
    """An apt-get on PATH that fails ``lock_failures`` times as apt does on a held lock."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(parents=True)
    count = tmp_path / "count"
    count.write_text("0")
    (bin_dir / "apt-get").write_text(f"""#!/usr/bin/env bash
n=$(cat {count}); echo $((n + 1)) > {count}
echo "$@" >> {tmp_path}/args
{'echo "E: Unable to locate package nope" >&2; exit 100' if other_error else ''}
if [ "$n" -lt {lock_failures} ]; then
  echo "E: Could not get lock /var/lib/apt/lists/lock. It is held by process 1 (apt-get)" >&2
  exit 100
fi
echo installed
""")
    (bin_dir / "apt-get").chmod(0o755)
    (bin_dir / "sudo").write_text('#!/usr/bin/env bash\nexec "$@"\n')
    (bin_dir / "sudo").chmod(0o755)
    return {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}", "APT_LOCK_POLL_S": "0.05"}


def test_a_held_lock_is_waited_for(tmp_path):
    env = _fake_apt(tmp_path, lock_failures=3)
    r = _run("apt_get update -qq", env)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "count").read_text().strip() == "4"
    assert r.stderr.count("waiting for another apt") == 1  # said once
    assert "DPkg::Lock::Timeout=600" in (tmp_path / "args").read_text()  # dpkg's lock: apt waits


def test_other_errors_and_a_lock_held_too_long_fail(tmp_path):
    env = _fake_apt(tmp_path, lock_failures=0, other_error=True)
    r = _run("apt_get install -y nope", env)
    assert r.returncode != 0 and "Unable to locate package nope" in r.stderr
    assert (tmp_path / "count").read_text().strip() == "1"  # not retried
    env = {**_fake_apt(tmp_path / "b", lock_failures=10 ** 6), "APT_LOCK_WAIT_S": "1"}
    t0 = time.monotonic()
    r = _run("apt_get update", env)
    assert r.returncode != 0 and "Could not get lock" in r.stderr
    assert time.monotonic() - t0 < 10


@pytest.mark.skipif(os.name != "posix" or not hasattr(os, "geteuid") or os.geteuid() != 0
                    or shutil.which("apt-get") is None or not Path("/var/cache/apt/archives").is_dir(),
                    reason="needs apt-get and root")
def test_the_real_apt_waits_for_its_download_lock():
    """apt 2.6 fails at once on the download cache's lock, whatever DPkg::Lock::Timeout says."""
    held = threading.Event()

    def hold():
        fd = os.open("/var/cache/apt/archives/lock", os.O_RDWR | os.O_CREAT)
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX)  # apt's own kind of lock (fcntl)
            held.set()
            time.sleep(2.0)
        finally:
            os.close(fd)
    t = threading.Thread(target=hold)
    t.start()
    held.wait(10)
    t0 = time.monotonic()
    # bash is always installed: apt takes its locks, finds nothing to do
    r = _run("apt_get install -y -qq --no-install-recommends bash",
             {**os.environ, "APT_LOCK_POLL_S": "0.2"})
    t.join()
    assert r.returncode == 0, r.stderr
    assert time.monotonic() - t0 >= 1.5
