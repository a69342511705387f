"""GDAL's and libtiff's own lines on stderr, kept off the command line's stderr.

A write GDAL cannot complete (a full disk, a file size limit) makes libtiff print a line per
block straight to the process's stderr (``_tiffWriteProc: No space left on device.``), from
C, past Python's ``sys.stderr`` and past rasterio's error handler. :class:`GdalLines` points
file descriptor 2 at a pipe for the command's run: such lines are kept (the error's one line
carries them as its cause), every other byte is passed on to the real stderr as it comes (a
progress line too).
"""
from __future__ import annotations

import os
import re
import sys

from prismstation.io.threads import helper_thread

#: lines of GDAL (``ERROR 1: …``) and of libtiff (``TIFFWriteDirectory: …``, ``_tiffWriteProc: …``)
GDAL_LINE = re.compile(rb"^(ERROR \d+: |Warning \d+: |_?TIFF\w*: |_tiff\w+: )")
#: a start of line that may become one of them (held until its end of line)
_MAYBE = re.compile(rb"^(E|ER|ERR|ERRO|ERROR|ERROR \d*|W\w*|W\w* \d*|_|_?T\w*|_tiff\w*)$")


_terminal = False  # fd 2 was a terminal before it was pointed at the pipe


def stderr_is_terminal() -> bool:
    """Whether stderr is a terminal (a progress line is shown): as it was before
    :class:`GdalLines` pointed it at its pipe."""
    return _terminal or sys.stderr.isatty()


class GdalLines:
    """``with GdalLines() as lines:`` — fd 2 through a filter for the block; ``lines.kept``:
    GDAL's and libtiff's lines, decoded, in order, once each. Does nothing where fd 2 cannot
    be redirected, or when not ``active``."""

    def __init__(self, active: bool = True):
        self.kept: list[str] = []
        self._saved = None
        self._active = active

    def __enter__(self):
        global _terminal
        if not self._active:
            return self
        try:
            _terminal = os.isatty(2)
            sys.stderr.flush()
            self._saved = os.dup(2)
            r, w = os.pipe()
            os.dup2(w, 2)
            os.close(w)
        except (OSError, ValueError, AttributeError):
            self._saved = None
            return self
        self._thread = helper_thread(self._pump, r, name="gdal-stderr")
        return self

    def __exit__(self, *exc):
        global _terminal
        _terminal = False
        if self._saved is None:
            return
        try:
            sys.stderr.flush()
        except (OSError, ValueError, AttributeError):
            pass
        os.dup2(self._saved, 2)   # the pipe's last write end closes: the pump reads its end
        self._thread.join(timeout=2)
        os.close(self._saved)
        self._saved = None

    def cause(self) -> str:
        """The kept lines as one cause (``_tiffWriteProc: File too large``), or ''."""
        return "; ".join(self.kept[:3])

    def _keep(self, line: bytes) -> None:
        text = line.decode("utf-8", "replace").strip().rstrip(".")
        if text not in self.kept:
            self.kept.append(text)

    def _pass(self, data: bytes) -> None:
        if data:
            try:
                os.write(self._saved, data)
            except OSError:
                pass

    def _pump(self, r: int) -> None:
        held = b""
        try:
            while True:
                chunk = os.read(r, 65536)
                if not chunk:
                    break
                held += chunk
                *lines, held = held.split(b"\n")
                for line in lines:
                    if GDAL_LINE.match(line):
                        self._keep(line)
                    else:
                        self._pass(line + b"\n")
                if held and not (GDAL_LINE.match(held) or _MAYBE.match(held)):
                    self._pass(held)    # a progress line ("\r 42 %"), passed on as it comes
                    held = b""
        finally:
            if held:
                (self._keep if GDAL_LINE.match(held) else self._pass)(held)
            os.close(r)
