"""The ``rmpl`` command line: one module per command, each ``register(sub)`` + ``run(args)``."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from rmpl.errors import InputError

__all__ = ["main"]

COMMANDS = {
    "triangulate": "rmpl.cli.triangulate",
    "convert-calib": "rmpl.cli.convert_calib",
    "lift": "rmpl.cli.lift",
    "poses": "rmpl.cli.poses",
    "train": "rmpl.cli.train",
    "evaluate": "rmpl.cli.evaluate",
    "bench": "rmpl.cli.bench",
    "example": "rmpl.cli.example",
    "run": "rmpl.cli.run",
    "generate": "rmpl.cli.generate",
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


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 success, 2 bad input)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, format="%(message)s")
    try:
        return int(args.run(args) or 0)
    except (InputError, FileNotFoundError, ValueError) as e:
        print(f"rmpl {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
