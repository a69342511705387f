"""Command line ``prismstation``.

Each module of this package (other than ones starting with ``_``) defines
``register(subparsers)``, which adds one or more sub-commands and sets ``func`` on them:
``func(args) -> int`` (the exit status). Modules are discovered, so adding a command is
adding a module. Bad input, a raster that cannot be read and a file that cannot be written
raise :class:`prismstation.errors.PrismError` naming the file; :func:`main` prints it as one
line on stderr and exits 2 — never a traceback. An ``OSError`` no reader or writer named (none
is known) is still one line and exit 2.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys

from prismstation import __version__
from prismstation.cli._common import end_progress
from prismstation.cli._gdal_lines import GdalLines
from prismstation.errors import PrismError
from prismstation.io.raster import gdal_env


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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        if args.command is None:  # bare `prismstation` opens the workstation
            args = parser.parse_args(["gui"] + list(argv or sys.argv[1:]))
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
    except (PrismError, OSError) as exc:
        end_progress()
        text, cause = str(exc), gdal_lines.cause()
        if cause and cause not in text:
            text = f"{text} (printed by GDAL: {cause})"
        print(f"prismstation {args.command}: {text}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
