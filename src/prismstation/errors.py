"""Exceptions of prismstation: one root, subclasses that also inherit the matching builtin.

Every reader raises :class:`InputError` naming the file, the line (1-based, when the input
has lines) and the problem; the command line prints ``str(error)`` and exits 2.
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
    """A raster could not be opened or read."""


class Cancelled(PrismError):
    """The operation was cancelled by its caller (through its progress callback); nothing was
    written."""


class DegenerateGeometry(ModelError):
    """The points cannot determine the parameters: too few, nearly collinear, or otherwise
    ill-conditioned (the message says which and the condition number)."""
