"""Command line ``prismstation``.

Each module of this package (other than ones starting with ``_``) defines
``register(subparsers)``, which adds one or more sub-commands and sets ``func`` on them:
``func(args) -> int`` (the exit status). Modules are discovered, so adding a command is
adding a module. Bad input, a raster that cannot be read and a file that cannot be written
raise :class:`prismstation.errors.PrismError` naming the file; :func:`main` prints it as one
line on stderr and exits 2 — never a traceback. An ``OSError`` no reader or writer named (none
is known) is still one line and exit 2. Anything else — a bug, memory running out — is one line
naming the command, its file and the error, exit 1, with the traceback written to a log file
under the user's state folder (the line gives its path); Ctrl+C is one line and exit 130.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys

from prismstation import __version__
from prismstation.errors import PrismError


#: commands that open the window: their stderr is left alone (a crash's dump must reach it)
WINDOW_COMMANDS = ("gui", "demo")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="prismstation", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"prismstation {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__name__}.{info.name}").register(sub)
    return parser


#: the arguments that name a command's main file, in the order they are looked for
SUBJECT_ARGS = ("project", "input", "image", "dsm", "reference", "dem", "outdir")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--version"]:  # before the parser: its commands import the whole stack
        print(f"prismstation {__version__}")
        return 0
    try:
        return _main(argv, _keep)
    except KeyboardInterrupt:
        _end_progress()
        print(f"prismstation {_command(argv)}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of the output went away (`prismstation fit p | head`): quietly, as other
        # commands do, with the shell's status for SIGPIPE; nothing more is written to the pipe
        _silence_stdio()
        return 141
    except (Exception, MemoryError) as exc:  # a bug or the memory: one line, the traceback logged
        _end_progress()
        print(unexpected_line(_command(argv), _subject(_kept[-1] if _kept else None), exc), file=sys.stderr)
        return 1
    finally:
        _kept.clear()


_kept: list = []  # the parsed arguments, for the line of an unexpected error


def _silence_stdio() -> None:
    """Point stdout and stderr at the null device, so that the interpreter's last flush finds
    no closed pipe."""
    import os
    devnull = os.open(os.devnull, os.O_WRONLY)
    for stream in (sys.stdout, sys.stderr):
        try:
            os.dup2(devnull, stream.fileno())
        except (OSError, ValueError):   # not a file (captured in tests): nothing to flush there
            pass


def _keep(args):
    _kept.append(args)
    return args


def _command(argv) -> str:
    return next((a for a in argv if not a.startswith("-")), "gui")


def _subject(args) -> str | None:
    for key in SUBJECT_ARGS:
        value = getattr(args, key, None)
        if isinstance(value, str) and value:
            return value
    return None


def _end_progress() -> None:
    if "prismstation.cli._common" in sys.modules:
        sys.modules["prismstation.cli._common"].end_progress()


def unexpected_line(command: str, subject: str | None, exc: BaseException) -> str:
    """The one line of an unexpected error: the command, its file, the error, and where its
    traceback was logged (:func:`log_traceback`)."""
    what = "out of memory" if isinstance(exc, MemoryError) else f"unexpected error ({type(exc).__name__}: " \
        f"{' '.join(str(exc).split())[:200]})"
    if isinstance(exc, ImportError) and "map segment" in str(exc):  # a library could not be loaded
        what = f"out of memory while starting ({' '.join(str(exc).split())[:200]})"
    log = log_traceback(exc, command, subject)
    where = f"{subject}: " if subject else ""
    return f"prismstation {command}: {where}{what}; " + (f"details in {log}" if log else "no log could be written")


def state_folder():
    """Where prismstation keeps its logs: ``$XDG_STATE_HOME/prismstation`` (default
    ``~/.local/state/prismstation``)."""
    import os
    from pathlib import Path
    base = os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state"
    return Path(base) / "prismstation"


def log_traceback(exc: BaseException, command: str, subject: str | None):
    """Write ``exc``'s traceback to ``<state folder>/crash-<time>-<pid>.log``; its path, or
    None when it cannot be written (the error's line is printed all the same)."""
    import os
    import time
    import traceback
    try:
        folder = state_folder()
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"crash-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.log"
        text = (f"prismstation {__version__}, command {command!r}, file {subject!r}\n"
                f"argv: {sys.argv!r}\n\n" + "".join(traceback.format_exception(exc)))
        path.write_text(text, encoding="utf-8")
        return path
    except Exception:  # a full disk, no home folder: the line says no log
        return None


def _main(argv: list[str], keep) -> int:
    # start-up: the stack (rasterio, numpy, the commands) loads here, not for --version
    from prismstation.cli._common import end_progress
    from prismstation.cli._gdal_lines import GdalLines
    from prismstation.io.raster import gdal_env

    parser = build_parser()
    args = keep(parser.parse_args(argv))
    if not getattr(args, "func", None):
        if args.command is None:  # bare `prismstation` opens the workstation
            args = keep(parser.parse_args(["gui"] + argv))
        else:
            parser.print_help()
            return 2
    # GDAL's own lines on stderr (a failed write prints one per block, from Python's logging
    # and from libtiff in C): the error's one line below names the file and carries them
    logging.getLogger("rasterio._env").setLevel(logging.CRITICAL)
    gdal_lines = GdalLines(active=args.command not in WINDOW_COMMANDS)
    try:
        with gdal_lines, gdal_env():
            status = int(args.func(args) or 0)
        for line in gdal_lines.kept:  # no error to carry them: as GDAL printed them
            print(line, file=sys.stderr)
        return status
    except BrokenPipeError:
        raise
    except (PrismError, OSError) as exc:
        end_progress()
        text, cause = str(exc), gdal_lines.cause()
        if cause and cause not in text:
            text = f"{text} (printed by GDAL: {cause})"
        print(f"prismstation {args.command}: {text}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
