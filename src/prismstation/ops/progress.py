"""The one progress-and-cancel protocol of the long operations.

An operation takes ``progress``: a callable ``progress(fraction, message="")`` with ``fraction``
in 0–1, called from the thread that runs the operation. It returns ``False`` when the caller
wants the operation to stop (any other value, ``None`` included, means go on). Operations call
:func:`checkpoint`, which raises :class:`Cancelled` on ``False``; a cancelled operation leaves no
partial output behind.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Callable

from prismstation.errors import Cancelled
from prismstation.io.atomic import atomic_path

__all__ = ["Cancelled", "ProgressFn", "checkpoint", "partial_output", "scaled"]

ProgressFn = Callable[..., "bool | None"]


def checkpoint(progress: ProgressFn | None, fraction: float, message: str = "") -> None:
    """Report ``fraction`` (0–1) and ``message``; raise :class:`Cancelled` if asked to stop."""
    if progress is not None and progress(min(max(float(fraction), 0.0), 1.0), message) is False:
        raise Cancelled("cancelled")


def scaled(progress: ProgressFn | None, start: float, stop: float) -> ProgressFn | None:
    """``progress`` seen through a sub-range: ``f`` in 0–1 reports ``start + f (stop − start)``."""
    if progress is None:
        return None
    return lambda f, message="": progress(start + (stop - start) * float(f), message)


@contextmanager
def partial_output(path, check=None):
    """Write to a temporary path (a str) beside ``path``: checked (``check(tmp)``, see
    :func:`prismstation.io.atomic.atomic_path`) and renamed to ``path`` when the block ends
    without error, removed otherwise — a cancelled or failed operation leaves no output file
    and does not touch an existing one; a failure to write is a
    :class:`~prismstation.errors.WriteError` naming ``path``."""
    with atomic_path(path, check=check) as part:
        yield str(part)
