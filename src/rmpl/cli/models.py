"""List the shipped models: joint set, inputs, size, how each was chosen, when rmpl run picks it.

The table and the rule that picks a model live in rmpl.models (rmpl.models.choose_model);
docs/results.md has the command of every figure.

Example: rmpl models
"""

from __future__ import annotations

import argparse


def register(parser: argparse.ArgumentParser) -> None:
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rmpl.models import table

    print(table())
    return 0
