"""The one progress-and-cancel protocol of the long operations.

An operation takes ``progress``: a callable ``progress(fraction, message="")`` with ``fraction``
in 0–1, called from the thread that runs the operation. It returns ``False`` when the caller
wants the operation to stop (any other value, ``None`` included, means go on). Operations call
:func:`checkpoint`, which raises :class:`Cancelled` on ``False``; a cancelled operation leaves no
partial output behind.
"""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from prismstation.errors import Cancelled

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
def partial_output(path):
    """Write to a temporary path beside ``path``: renamed to ``path`` when the block ends
    without error, removed otherwise (a cancelled or failed operation leaves no output file
    and does not touch an existing one)."""
    out = Path(path)
    part = out.with_name(f".{out.name}.part")
    try:
        yield str(part)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    os.replace(part, out)
