"""The ``rmpl`` command line: one module per command, each ``register(sub)`` + ``run(args)``."""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import sys

from rmpl.errors import InputError

__all__ = ["main"]

COMMANDS = {  # in the order of the user's chain, then the tools
    "calibrate": "rmpl.cli.calibrate",
    "sync": "rmpl.cli.sync",
    "run": "rmpl.cli.run",
    "batch": "rmpl.cli.batch",
    "simulate": "rmpl.cli.simulate",
    "lift": "rmpl.cli.lift",
    "triangulate": "rmpl.cli.triangulate",
    "convert-calib": "rmpl.cli.convert_calib",
    "evaluate": "rmpl.cli.evaluate",
    "example": "rmpl.cli.example",
    "models": "rmpl.cli.models",
    "bench": "rmpl.cli.bench",
    "benchmark": "rmpl.cli.benchmark",
    "poses": "rmpl.cli.poses",
    "generate": "rmpl.cli.generate",
    "train": "rmpl.cli.train",
}


def build_parser() -> argparse.ArgumentParser:
    from rmpl import __version__

    parser = argparse.ArgumentParser(prog="rmpl", description=__doc__)
    parser.add_argument("--version", action="version", version=f"rmpl {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module in COMMANDS.items():
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError as e:
            if e.name == module:
                continue  # command not built yet
            raise
        mod.register(
            sub.add_parser(
                name,
                help=mod.__doc__.splitlines()[0],
                description=mod.__doc__,
                # keep the docstrings' example lines as written
                formatter_class=argparse.RawDescriptionHelpFormatter,
            )
        )
    return parser


#: What a path had to be, by the error the operating system gave for it.
_EXPECTED = {
    errno.EACCES: "a path you may read (input) or write (output)",
    errno.EPERM: "a path you may read (input) or write (output)",
    errno.EISDIR: "a file, not a directory",
    errno.ENOTDIR: "a folder (a part of this path is a regular file)",
    errno.EEXIST: "a folder, or nothing (a regular file is in the way)",
    errno.ENOENT: "an existing file or folder",
    errno.ENOSPC: "free space on the disk",
    errno.EROFS: "a writable file system",
    errno.ENAMETOOLONG: "a shorter path",
}


def os_error_message(e: OSError) -> str:
    """One line naming the path and what it had to be: ``out/x: expected a folder, got ...``."""
    if e.filename is None:
        return str(e)
    path = e.filename
    if e.filename2 is not None:
        path = f"{e.filename} -> {e.filename2}"
    expected = _EXPECTED.get(e.errno or -1, "a usable path")
    return str(InputError(path, None, expected, e.strerror or type(e).__name__))


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code: 0 success, 2 bad input (an option, a file, a
    filesystem error, or a result with nothing estimated), one line on stderr; 3 (``rmpl
    run``) a person's views disagree in most frames, outputs written."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, format="%(message)s")
    try:
        return int(args.run(args) or 0)
    except (InputError, ValueError) as e:
        message = str(e)
    except OSError as e:  # an output under a regular file, a locked folder, a full disk, ...
        message = os_error_message(e)
    print(f"rmpl {args.command}: error: {message}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
