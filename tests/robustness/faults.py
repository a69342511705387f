"""Fault injection shared by the fault suite: broken tiled GeoTIFFs, a full or read-only file
system, a writer limited to N bytes, and the command-line contract on a fault.

The contract (every command, every fault): exit status 2 and exactly one line on stderr,
``prismstation COMMAND: FILE: what failed``, naming the file at fault; no traceback; no
"wrote" for a file that is not there; no file — partial, temporary or corrupt — left beside
the target; the project file byte for byte as it was.

A full file system is a small tmpfs mounted for the test where one can be (root on Linux),
filled so that ``free`` bytes are left: the kernel's own ENOSPC. Everywhere (CI need not be
root) the same commands also run with no file allowed past N bytes (:func:`file_size_limit`):
the kernel fails the write past it with EFBIG inside the very library call that a full disk
fails in, so it exercises the same paths (Python's ``write``, GDAL's and libtiff's block
writes, Qt's), unlike a patched Python ``write`` that GDAL and Qt never call.
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import io
import os
import resource
import shutil
import signal
import subprocess
import sys
import threading
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path

import rasterio


SIM_SIZE = 800          # pixels a side: 2 × 2 tiles of 512 per image


# ----------------------------------------------------------------------- the simulated triplet
def shared_sim(tmp_path_factory) -> Path:
    """A simulated triplet project (``tests/gui/sim_project.make_sim``) made once per test run,
    shared by the xdist workers (a lock on the run's common folder), with a tiled, deflated
    copy of its reference DEM (``srtm_tiled.tif``: a bit flip in it is a decoding error)."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent              # the run's folder, common to its workers
    d = base / "faults_sim"
    with open(base / "faults_sim.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (d / "done").exists():
            from tests.gui.sim_project import make_sim
            shutil.rmtree(d, ignore_errors=True)
            make_sim(d, size=SIM_SIZE, seed=7)
            with rasterio.open(d / "srtm.tif") as src:
                profile = dict(src.profile, tiled=True, blockxsize=16, blockysize=16,
                               compress="deflate")
                with rasterio.open(d / "srtm_tiled.tif", "w", **profile) as dst:
                    dst.write(src.read())
            (d / "done").touch()
    return d


def copy_sim(master: Path, target: Path) -> Path:
    shutil.copytree(master, target, ignore=shutil.ignore_patterns("done"))
    return target


# ----------------------------------------------------------------------- broken rasters
def tile_spans(path) -> list[tuple[int, int]]:
    """``(offset, bytes)`` of every full-resolution tile of band 1 (GDAL's TIFF metadata)."""
    with rasterio.open(path) as ds:
        bh, bw = ds.block_shapes[0]
        spans = []
        for r in range(-(-ds.height // bh)):
            for c in range(-(-ds.width // bw)):
                spans.append((int(ds.get_tag_item(f"BLOCK_OFFSET_{c}_{r}", "TIFF", bidx=1)),
                              int(ds.get_tag_item(f"BLOCK_SIZE_{c}_{r}", "TIFF", bidx=1))))
    return spans


def truncate(path, keep: float = 0.5) -> None:
    """Keep the first ``keep`` of the file (a copy cut short; the directory at its head
    stays, the tiles at its end are gone)."""
    path = Path(path)
    os.truncate(path, int(path.stat().st_size * keep))


def bitflip(path, tiles=None) -> None:
    """Flip one bit in the middle of the compressed data of each tile (or of the tiles whose
    indexes, in row order, are in ``tiles``): each is a deflate error when read."""
    path = Path(path)
    data = bytearray(path.read_bytes())
    for i, (off, size) in enumerate(tile_spans(path)):
        if tiles is None or i in tiles:
            data[off + size // 2] ^= 0x10
    path.write_bytes(bytes(data))


BREAKS = {"truncated": truncate, "bitflip": bitflip}


# ----------------------------------------------------------------------- file systems
_MOUNT: list = []


def can_mount() -> bool:
    """A tmpfs can be mounted here (root on Linux, mount allowed): tried once."""
    if not _MOUNT:
        ok = False
        if sys.platform.startswith("linux") and os.geteuid() == 0 and shutil.which("mount"):
            probe = Path(os.environ.get("TMPDIR", "/tmp")) / f"prism_mount_probe_{os.getpid()}"
            probe.mkdir(exist_ok=True)
            try:
                ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(probe)],
                                    capture_output=True).returncode == 0
                if ok:
                    subprocess.run(["umount", str(probe)], check=True)
            finally:
                probe.rmdir()
        _MOUNT.append(ok)
    return _MOUNT[0]


@contextmanager
def tmpfs(directory: Path, size_kb: int = 2048, read_only: bool = False):
    """Mount a tmpfs of ``size_kb`` on ``directory`` for the block (read-only: nothing can be
    created in it)."""
    directory.mkdir(parents=True, exist_ok=True)
    opts = f"size={size_kb}k" + (",ro" if read_only else "")
    subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(directory)], check=True)
    try:
        yield directory
    finally:
        if subprocess.run(["umount", str(directory)], capture_output=True).returncode:
            subprocess.run(["umount", "-l", str(directory)], capture_output=True)


@contextmanager
def read_only_folder(directory: Path):
    """A folder nothing can be created in, for the block: a read-only tmpfs where one can be
    mounted, else mode 0555 (skips as root, whom a folder's mode does not stop)."""
    import pytest
    if can_mount():
        with tmpfs(directory, 64, read_only=True):
            yield directory
        return
    if os.geteuid() == 0:
        pytest.skip("root ignores a folder's mode and no tmpfs can be mounted")
    directory.mkdir(parents=True, exist_ok=True)
    directory.chmod(0o555)
    try:
        yield directory
    finally:
        directory.chmod(0o755)


def fill(directory: Path, free: int) -> None:
    """Fill ``directory``'s file system with ``.filler`` until ``free`` bytes (whole pages) are
    left."""
    fd = os.open(directory / ".filler", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    try:
        chunk = b"\0" * 65536
        while True:
            try:
                if os.write(fd, chunk) == 0:
                    break
            except OSError as exc:
                if exc.errno != errno.ENOSPC:
                    raise
                break
        os.ftruncate(fd, max(0, os.fstat(fd).st_size - free))
    finally:
        os.close(fd)
    st = os.statvfs(directory)
    assert abs(st.f_bavail * st.f_frsize - free) <= 2 * st.f_frsize, (st.f_bavail * st.f_frsize, free)


def listing(directory: Path) -> list[str]:
    """The files under ``directory`` (folders a command made and left empty are no file)."""
    return sorted(str(p.relative_to(directory)) for p in Path(directory).rglob("*")
                  if not p.is_dir())


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# ----------------------------------------------------------------------- running the commands
class _Pipe:
    """File descriptor ``fd`` pointed at a pipe for the block, its bytes read by a thread (a
    pipe is no file: a file size limit does not stop it, a full disk does not fill it)."""

    def __init__(self, fd: int):
        self.fd, self.chunks = fd, []

    def __enter__(self):
        self.saved = os.dup(self.fd)
        r, w = os.pipe()
        os.dup2(w, self.fd)
        os.close(w)
        self.thread = threading.Thread(target=self._read, args=(r,), daemon=True)
        self.thread.start()
        return self

    def _read(self, r):
        while chunk := os.read(r, 65536):
            self.chunks.append(chunk)
        os.close(r)

    def __exit__(self, *exc):
        os.dup2(self.saved, self.fd)
        os.close(self.saved)
        self.thread.join(timeout=5)

    def text(self) -> str:
        return b"".join(self.chunks).decode("utf-8", "replace")


class Output:
    """What the block printed: ``out``, ``err`` (text), once it ended."""
    out = err = ""


@contextmanager
def captured():
    """Python's and the file descriptors' output of the block, into pipes (read by threads):
    GDAL's and libtiff's lines printed from C are seen, and no write of the block's output
    lands in a file (pytest's own capture is one), which a file size limit or a full disk
    would fail."""
    got = Output()
    so, se = io.StringIO(), io.StringIO()
    with _Pipe(1) as fd1, _Pipe(2) as fd2, redirect_stdout(so), redirect_stderr(se):
        yield got
    got.out, got.err = so.getvalue() + fd1.text(), se.getvalue() + fd2.text()


def run_cli(argv) -> tuple[int, str, str]:
    """``prismstation.cli.main(argv)`` in this process: ``(status, stdout, stderr)``
    (:func:`captured`)."""
    from prismstation.cli import main
    with captured() as got:
        rc = main([str(a) for a in argv])
    return rc, got.out, got.err


@contextmanager
def file_size_limit(limit: int):
    """No file of this process may grow past ``limit`` bytes for the block (``RLIMIT_FSIZE``,
    ``SIGXFSZ`` ignored): a write past it fails in the kernel with EFBIG, through the very
    calls a full disk fails in (Python's, GDAL's, libtiff's, Qt's). Needs no privilege."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    limit = min(limit, hard) if hard != resource.RLIM_INFINITY else limit
    handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, handler)


def assert_clean_failure(result, command: str, names) -> str:
    """Exit 2, one line ``prismstation COMMAND: …`` naming ``names`` (one of them, when a
    tuple), no traceback, no "wrote"; returns the line."""
    rc, out, err = result
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1, (rc, out, err)
    assert lines[0].startswith(f"prismstation {command}: "), lines[0]
    names = (names,) if isinstance(names, str) else names
    assert any(n in lines[0] for n in names), f"{names!r} not named: {lines[0]}"
    assert "wrote" not in out.lower(), out
    return lines[0]
