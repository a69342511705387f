"""Atomic writes: every file prismstation writes goes through :func:`atomic_path`.

A writer writes a temporary file beside the target (``.NAME.XXXX.partEXT`` in the same folder,
so that the rename is atomic), the file is checked (its size is what was written; a writer may
pass a ``check`` of its own: a PDF ends with ``%%EOF``, a GeoTIFF reopens and reads its last
blocks), flushed to the disk (fsync) and renamed onto the target. On any error the temporary
file and the side files GDAL may have made beside it are removed, and the failure is raised as
:class:`prismstation.errors.WriteError` naming the target and the cause (``cannot write: No
space left on device``); the target, or its previous version, is untouched. Errors of
prismstation's own (a cancel, a read that failed) pass through unchanged.

The permissions of a new file are those of a plain new file (0666 less the umask); a file
written over keeps its previous mode. With ``keep_backup`` the previous version is kept as
``NAME.bak``, made *before* the one rename that puts the new file in place (a hard link to the
previous version, or a copy where the file system has no links, itself put in place by a rename):
the target is replaced by exactly one ``os.replace``, so at every moment — a crash, a
``kill -9``, an I/O error at any step — the target's path holds either its previous version or
the new one, whole.
"""
from __future__ import annotations

import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

from prismstation.errors import PrismError, WriteError
from prismstation.io.threads import helper_thread

#: side files GDAL may write beside a raster
SIDE_FILES = (".aux.xml", ".ovr", ".msk")

_umask: int | None = None


def _new_file_mode() -> int:
    """0666 less the process's umask (read once; from /proc where it can be, since setting the
    umask to read it is not safe while other threads create files)."""
    global _umask
    if _umask is None:
        try:
            line = next(ln for ln in Path("/proc/self/status").read_text().splitlines()
                        if ln.startswith("Umask:"))
            _umask = int(line.split()[1], 8)
        except (OSError, StopIteration, ValueError, IndexError):
            _umask = os.umask(0o022)
            os.umask(_umask)
    return 0o666 & ~_umask


def _gdal_error(exc: BaseException) -> bool:
    """A rasterio or GDAL error (checked without importing rasterio)."""
    if "rasterio" not in sys.modules:
        return False
    from rasterio._err import CPLE_BaseError
    from rasterio.errors import RasterioError
    return isinstance(exc, (RasterioError, CPLE_BaseError))


def cause_text(exc: BaseException, name=None) -> str:
    """What went wrong, in one line: an OS error's message, or GDAL's messages along the
    exception's chain (rasterio's own "See previous exception" and messages already contained
    in an earlier one left out; ``name``, the file the caller names itself, cut from them)."""
    if isinstance(exc, PrismError):
        return str(exc)
    if isinstance(exc, OSError) and not _gdal_error(exc) and exc.strerror:
        return exc.strerror
    parts, e = [], exc
    while e is not None and len(parts) < 4:
        text = " ".join(str(e).split()).rstrip(".")
        for n in (name, os.path.basename(name)) if name else ():
            text = text.replace(f"{n}, ", "").replace(f"{n}: ", "")
        if text and "See previous exception" not in text and not any(text in p for p in parts):
            parts.append(text)
        e = e.__cause__ or e.__context__
    return "; ".join(parts) or type(exc).__name__


#: a GDAL write error with less free space than this beside the file is a full disk
FULL_DISK_BYTES = 4 << 20


def free_bytes(folder) -> int | None:
    """Bytes an unprivileged writer may still use on ``folder``'s file system (None: unknown)."""
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return None
    return st.f_bavail * st.f_frsize


class FreeSpaceWatch:
    """The least free space seen on ``folder``'s file system while the block runs
    (``with FreeSpaceWatch(folder) as w: …; w.least``), sampled every ``interval`` s on a
    thread and once more at the end: a writer that fails on a full disk and cleans up after
    itself (GDAL removes a temporary overview file before it raises) leaves more space free
    than there was when it failed, and a message must say the latter."""

    def __init__(self, folder, interval: float = 0.05):
        self.folder, self.interval = folder, interval
        self.least: int | None = None

    def _sample(self) -> None:
        free = free_bytes(self.folder)
        if free is not None and (self.least is None or free < self.least):
            self.least = free

    def __enter__(self):
        import threading
        self._stop = threading.Event()
        self._sample()

        def run():
            while not self._stop.wait(self.interval):
                self._sample()
        self._thread = helper_thread(run, name="free space")
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        return False


def write_error(target, exc: BaseException, what: str = "cannot write",
                free: int | None = None) -> WriteError:
    """The :class:`WriteError` for ``exc`` met while writing ``target``. GDAL says only "write
    error": with ``free`` (bytes left beside the file when it failed) under
    :data:`FULL_DISK_BYTES` the message says the disk is full."""
    errno = exc.errno if isinstance(exc, OSError) and not _gdal_error(exc) else None
    cause = cause_text(exc)
    if _gdal_error(exc) and free is not None and free < FULL_DISK_BYTES:
        cause = f"the disk is full ({free} bytes free; GDAL: {cause})"
    return WriteError(f"{what}: {cause}", target, errno if isinstance(errno, int) else None)


def _remove(tmp: Path) -> None:
    for p in [tmp] + [Path(str(tmp) + s) for s in SIDE_FILES]:
        try:
            p.unlink()
        except FileNotFoundError:
            pass
        except OSError:  # pragma: no cover - nothing more can be done
            pass


def _fsync(path: Path, directory: bool = False) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        if not directory:  # some file systems cannot fsync a folder: the rename still holds
            raise
    finally:
        os.close(fd)


# ---------------------------------------------------------------------- stale temporaries
def _host_tag() -> str:
    import hashlib
    import socket
    return hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:8]


#: ``<host>-<pid>`` in the name of every temporary file this process makes: a file whose
#: process is gone (a ``kill -9``, a crash) is known to be stale and is removed by the next run
OWNER_TAG = f"{_host_tag()}-{os.getpid()}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: it exists
        return True
    return True


def clean_stale(folder, prefix: str, folders: bool = False) -> list[Path]:
    """Remove the files in ``folder`` whose names start with ``prefix`` followed by an owner tag
    (:data:`OWNER_TAG`) of a process of this host that no longer runs and that belong to this
    user — the temporaries of a killed run (``.part.tif``, GDAL's ``.ovr.tmp`` beside them, a
    scratch copy; with ``folders``, folders too). A live process's files, another host's (a
    shared folder) and other users' are left alone. Returns what was removed; never raises."""
    host, me, removed = _host_tag(), os.getpid(), []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        if not e.name.startswith(prefix):
            continue
        tag = e.name[len(prefix):].split(".", 1)[0].split("_", 1)[0]
        h, _, pid = tag.partition("-")
        if h != host or not pid.isdigit() or int(pid) == me or _pid_alive(int(pid)):
            continue
        try:
            if e.stat(follow_symlinks=False).st_uid != os.getuid():
                continue
            if e.is_file(follow_symlinks=False):
                os.unlink(e.path)
            elif folders and e.is_dir(follow_symlinks=False):
                import shutil
                shutil.rmtree(e.path, ignore_errors=True)
            else:
                continue
            removed.append(Path(e.path))
        except OSError:
            pass
    return removed


def scratch_file(kind: str, suffix: str) -> Path:
    """A new empty file ``prismstation-<kind>-<owner tag>_XXXX<suffix>`` in the temporary
    folder, the stale ones of earlier killed runs removed first (:func:`clean_stale`). The
    caller removes it when done."""
    prefix = f"prismstation-{kind}-"
    clean_stale(tempfile.gettempdir(), prefix)
    fd, name = tempfile.mkstemp(prefix=f"{prefix}{OWNER_TAG}_", suffix=suffix)
    os.close(fd)
    return Path(name)


def _temporary_beside(target: Path) -> Path:
    """A new empty temporary file beside ``target`` (its folder made if absent), named
    ``.NAME.<owner tag>.XXXX.partEXT``, the stale ones of killed runs removed first; a
    :class:`WriteError` naming ``target`` when the folder cannot be written."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        clean_stale(target.parent, f".{target.name}.")
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.{OWNER_TAG}.", suffix=f".part{target.suffix}",
                                    dir=target.parent)
        os.close(fd)
    except OSError as exc:
        blocker = next((p for p in (target.parent, *target.parent.parents)
                        if p.exists() and not p.is_dir()), None)
        if blocker is not None:  # mkdir says only "File exists" or "Not a directory"
            raise WriteError(f"cannot write: {blocker} is a file, not a folder", target) from None
        raise write_error(target, exc) from None
    return Path(name)


def _backup(target: Path) -> None:
    """``target`` kept as ``target.bak``, ``target`` itself untouched (:func:`_link_or_copy`)."""
    _link_or_copy(target, target.with_name(target.name + ".bak"))


def _link_or_copy(source: Path, dest: Path) -> None:
    """``dest`` made the same file as ``source`` (``source`` untouched): a hard link to it
    (or, where links cannot be made, a copy flushed to the disk) made under a temporary name,
    then renamed onto ``dest`` (a previous ``dest`` stays whole until then)."""
    tmp = _temporary_beside(dest)
    try:
        try:
            os.unlink(tmp)
            os.link(source, tmp)
        except OSError:  # no hard links here (some network and FAT file systems): a copy
            import shutil
            shutil.copyfile(source, tmp)
            _fsync(tmp)
        os.replace(tmp, dest)
    except BaseException:
        _remove(tmp)
        raise


def _encoded(data: str | bytes) -> bytes:
    return data.encode("utf-8") if isinstance(data, str) else bytes(data)


def write_together(files: dict, keep_backup: bool = True) -> None:
    """Write several files (path → text or bytes) as one change: every file is written,
    checked and flushed beside its target first, the previous version of every target kept
    (``NAME.bak`` with ``keep_backup``, else a temporary link), and only then is each renamed
    onto its target, in the order given (the last is the one the others belong to: a project
    after its scene). A failure at any step puts the targets already replaced back as they were
    and leaves no file behind; a file whose bytes are already those at its target is not
    written. A ``kill -9`` between two renames leaves the earlier targets new and the later
    ones as they were (their previous versions in ``.bak``). A failure is a
    :class:`WriteError` naming the file it met."""
    staged: list[tuple[Path, Path]] = []     # (target, temporary)
    kept: dict[Path, Path | None] = {}       # target → its previous version
    done: list[Path] = []
    target = None
    try:
        for path, data in files.items():
            target, raw = Path(path), _encoded(data)
            try:
                if target.is_file() and target.stat().st_size == len(raw) and target.read_bytes() == raw:
                    continue
            except OSError:
                pass
            tmp = _temporary_beside(target)
            staged.append((target, tmp))
            with open(tmp, "wb") as fh:
                fh.write(raw)
            check_size(len(raw))(tmp)
            os.chmod(tmp, target.stat().st_mode & 0o7777 if target.exists() else _new_file_mode())
            _fsync(tmp)
        for target, _ in staged:
            prev = None
            if target.exists():
                prev = (target.with_name(target.name + ".bak") if keep_backup
                        else _temporary_beside(target))
                _link_or_copy(target, prev)
            kept[target] = prev
        for target, tmp in staged:
            os.replace(tmp, target)
            done.append(target)
    except BaseException as exc:
        for t in reversed(done):  # as they were
            try:
                if kept.get(t) is None:
                    os.unlink(t)
                else:
                    _link_or_copy(kept[t], t)
            except OSError:  # pragma: no cover - nothing more can be done
                pass
        for _, tmp in staged:
            _remove(tmp)
        if not keep_backup:
            for prev in kept.values():
                if prev is not None:
                    _remove(prev)
        if isinstance(exc, WriteError) and target is not None and exc.file is None:
            raise WriteError(exc.problem, target, exc.errno) from None
        if isinstance(exc, PrismError) or not isinstance(exc, OSError) or target is None:
            raise
        raise write_error(target, exc) from exc
    if not keep_backup:
        for prev in kept.values():
            if prev is not None:
                _remove(prev)
    for folder in {t.parent for t in done}:
        _fsync(folder, directory=True)


def check_writable(path) -> None:
    """Raise the :class:`WriteError` :func:`atomic_path` would raise at once for ``path`` (its
    folder cannot be made or written): called before long work, so that it does not end on a
    folder that was never writable. A full disk can only be met when writing."""
    os.unlink(_temporary_beside(Path(path)))


@contextmanager
def atomic_path(path, *, keep_backup: bool = False,
                check: Callable[[Path], None] | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` to write to; when the block ends normally,
    ``check(tmp)`` (it raises when the file is not what was meant), fsync, rename onto
    ``path``. On any error: the temporary file is removed and OS and GDAL errors become a
    :class:`WriteError` naming ``path``. See the module docstring."""
    target = Path(path)
    tmp = _temporary_beside(target)
    try:
        yield tmp
        if check is not None:
            check(tmp)
        mode = target.stat().st_mode & 0o7777 if target.exists() else _new_file_mode()
        os.chmod(tmp, mode)
        _fsync(tmp)
        if keep_backup and target.exists():
            _backup(target)
        os.replace(tmp, target)  # the one step that changes the target
        for s in SIDE_FILES:  # a side file GDAL wrote goes with its raster
            if os.path.exists(str(tmp) + s):
                os.replace(str(tmp) + s, str(target) + s)
    except BaseException as exc:
        free = free_bytes(target.parent) if _gdal_error(exc) else None  # before the space is freed
        _remove(tmp)
        if isinstance(exc, WriteError) and exc.file in (None, str(tmp)):  # a check's finding
            raise WriteError(exc.problem, target, exc.errno) from None
        if isinstance(exc, PrismError) or not (isinstance(exc, OSError) or _gdal_error(exc)):
            raise
        raise write_error(target, exc, free=free) from exc
    _fsync(target.parent, directory=True)  # the rename made durable


def check_size(expected: int) -> Callable[[Path], None]:
    """A ``check``: the file holds ``expected`` bytes (raises a :class:`WriteError` without a
    file, which :func:`atomic_path` names)."""
    def check(tmp: Path) -> None:
        size = os.path.getsize(tmp)
        if size != expected:
            raise WriteError(f"cannot write: {size} of {expected} bytes written")
    return check


def write_atomic(path, data: str | bytes, keep_backup: bool = True) -> None:
    """Write ``data`` (text as UTF-8 with ``\\n`` line ends, or bytes) to ``path`` atomically;
    with ``keep_backup`` the previous version is kept as ``path + '.bak'``. A failure is a
    :class:`WriteError`."""
    raw = _encoded(data)
    with atomic_path(path, keep_backup=keep_backup, check=check_size(len(raw))) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(raw)


def missing_block(ds) -> str | None:
    """The first block of a GeoTIFF ``ds`` (open rasterio dataset) that is not in its file (no
    offset, or data past the file's end) as ``band b, block (column, row)``, else None. GDAL
    reports a block it failed to write (a full disk, a file size limit) on stderr only, and
    reads a block never written as nodata: a file so written opens and reads, wrong."""
    if ds.driver != "GTiff":
        return None
    size = os.path.getsize(ds.name)
    bh, bw = ds.block_shapes[0]
    bands = range(1, ds.count + 1) if ds.profile.get("interleave") == "band" else (1,)
    for b in bands:
        for r in range(-(-ds.height // bh)):
            for c in range(-(-ds.width // bw)):
                off = ds.get_tag_item(f"BLOCK_OFFSET_{c}_{r}", "TIFF", bidx=b)
                n = ds.get_tag_item(f"BLOCK_SIZE_{c}_{r}", "TIFF", bidx=b)
                if not off or not n or int(off) + int(n) > size:
                    return f"band {b}, block ({c}, {r})"
    return None


def raster_check(width: int, height: int, count: int) -> Callable[[Path], None]:
    """A ``check`` for a raster just written: it opens, has this size and band count, every
    block is in the file (:func:`missing_block`), and its first and last blocks of every band
    read back (GDAL reports a failed write of its last blocks or of its directory only as the
    file is closed, if at all)."""
    def check(tmp: Path) -> None:
        import rasterio
        from rasterio.windows import Window
        try:
            with rasterio.open(tmp) as ds:
                if (ds.width, ds.height, ds.count) != (width, height, count):
                    raise WriteError(f"cannot write: the file written is {ds.width} × {ds.height} "
                                     f"× {ds.count}, not {width} × {height} × {count}")
                missing = missing_block(ds)
                if missing:
                    free = free_bytes(tmp.parent)
                    full = (f" (the disk is full: {free} bytes free)"
                            if free is not None and free < FULL_DISK_BYTES else "")
                    raise WriteError(f"cannot write: {missing} of the file was not written{full}")
                bh, bw = ds.block_shapes[0]
                for b in range(1, count + 1):
                    ds.read(b, window=Window(0, 0, min(bw, width), min(bh, height)))
                    r0, c0 = (height - 1) // bh * bh, (width - 1) // bw * bw
                    ds.read(b, window=Window(c0, r0, width - c0, height - r0))
        except WriteError:
            raise
        except Exception as exc:  # rasterio's and GDAL's errors: the file is not whole
            raise WriteError(f"cannot write: the file written does not read back "
                             f"({cause_text(exc)})") from None
    return check
