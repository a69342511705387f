"""Exceptions of prismstation: one root, subclasses that also inherit the matching builtin.

Every reader raises :class:`InputError` naming the file, the line (1-based, when the input
has lines) and the problem; a raster that cannot be read is a :class:`RasterReadError`, a file
that cannot be written a :class:`WriteError` (both also ``OSError``, as rasterio's are). The
command line prints ``str(error)`` and exits 2.
"""
from __future__ import annotations


class PrismError(Exception):
    """Root of every error prismstation raises on purpose."""


class InputError(PrismError, ValueError):
    """Bad input: a file, a line in it, and what is wrong there."""

    def __init__(self, problem: str, file: str | None = None, line: int | None = None):
        self.problem = problem
        self.file = None if file is None else str(file)
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        where = self.file or ""
        if self.line is not None:
            where = f"{where}, line {self.line}" if where else f"line {self.line}"
        return f"{where}: {self.problem}" if where else self.problem


class ModelError(PrismError, ValueError):
    """The model cannot be fitted with the data given (too few or collinear points...)."""


class RasterReadError(PrismError, OSError):
    """A raster could not be opened or read: the message names the file and the place (view,
    window or block) and GDAL's cause."""


class WriteError(PrismError, OSError):
    """A file could not be written (a full disk, a folder that cannot be written, a writer
    that failed): names the target and the cause. Nothing is left at the target; a previous
    version of it is untouched. ``errno`` is the cause's, when it had one."""

    def __init__(self, problem: str, file=None, errno: int | None = None):
        self.problem = problem
        self.file = None if file is None else str(file)
        super().__init__(str(self))
        self.errno = errno

    def __str__(self) -> str:
        return f"{self.file}: {self.problem}" if self.file else self.problem

    def __reduce__(self):  # through a process pool or a Dask worker, errno included
        return type(self), (self.problem, self.file, self.errno)


class Cancelled(PrismError):
    """The operation was cancelled by its caller (through its progress callback); nothing was
    written."""


class DegenerateGeometry(ModelError):
    """The points cannot determine the parameters: too few, nearly collinear, or otherwise
    ill-conditioned (the message says which and the condition number)."""
