"""Run one of the benchmarks behind docs/results.md, or list them.

rmpl benchmark                       # every benchmark, with what it measures
rmpl benchmark NAME --help           # one benchmark's own options
rmpl benchmark NAME [ARGS ...]       # the same as python -m rmpl.benchmarks.NAME ARGS
"""

from __future__ import annotations

import argparse


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?", default=None, help="the benchmark (omit: list them)")
    parser.add_argument(
        "args", nargs=argparse.REMAINDER, help="the benchmark's own arguments (NAME --help)"
    )
    parser.set_defaults(run=run)


def listing(names: dict[str, str]) -> str:
    """One line per benchmark: its name, then the first line of its docstring."""
    width = max((len(n) for n in names), default=0)
    return "\n".join(f"{name:<{width}}  {summary}" for name, summary in names.items())


def run(args: argparse.Namespace) -> int:
    from rmpl import benchmarks

    if args.name is None:
        print(listing(benchmarks.available()))
        print("\nrmpl benchmark NAME --help: one benchmark's options")
        return 0
    return benchmarks.run(args.name, args.args)
