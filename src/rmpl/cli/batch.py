"""Run every trial of a project folder: each one rmpl run, as a Ray task; one summary.

The project is a folder in Pose2Sim's layout (calibration/ and Config.toml at the top, trial
folders below, each with videos/, pose/ or pose-sync/ and its own Config.toml; participant
folders between them are fine) or rmpl's own (PROJECT/calibration/, one folder per trial
holding its videos, image folders or 2D files). A trial's own calibration/ overrides the
project's. See rmpl.project.layout for the rules.

An rmpl.toml at the project, participant and trial levels sets any rmpl run option by name
(method = "robust", max-gap = 10, no-pictures = true; paths relative to the file); the
trial's overrides the project's, the rmpl run options on this command line override both;
an unknown key is refused. From Pose2Sim's Config.toml rmpl reads frame_rate (--fps),
participant_height and participant_mass (shown in the summary beside rmpl's estimated
heights) and exclude_from_batch (trials skipped), and says so.

Each trial runs as one Ray task (--cpus-per-trial CPUs each, at most --workers at once): a
local Ray by default, or the running cluster at --address (start one with
`ray start --head`; every node must see PROJECT and OUT at the same paths). Each trial's
outputs go to OUT/<trial>/, written as a unit as by rmpl run; its log to
OUT/logs/<trial>.log. A trial whose inputs and options have not changed since its last
finished run (OUT/<trial>/trial.json, a fingerprint of rmpl's version, the options and the
inputs' names, sizes and modification times) is skipped; --force runs it again. A failed
trial is reported and the others go on. OUT/summary.md, summary.json and summary.html give
per trial its people, frames, reprojection error, view check, heights, time taken and links
to its report and viewer.

Exit status: 0 every trial done; 1 some trial failed (named on stderr and in the summary,
the others done); 2 bad input (no trial found, a bad option); 3 no trial failed but in some
trial a person's views disagree in most frames.

Examples:
  rmpl batch session/ --out session_rmpl/
  rmpl batch session/ --out session_rmpl/ --method robust --no-pictures
  ray start --head --num-cpus 2 && rmpl batch session/ --address 127.0.0.1:6379
  rmpl batch session/ --dry-run
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from rmpl.cli._common import at_least_one, positive

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("project", help="the project (session) folder, or one trial's folder")
    parser.add_argument("--out", default=None, help="output folder (default: PROJECT/rmpl-out)")
    parser.add_argument(
        "--address", default=None, help="a running Ray cluster to join (host:port, or 'auto')"
    )
    parser.add_argument(
        "--workers", type=at_least_one, default=None,
        help="at most N trials at once (default: the local Ray's CPUs, or the cluster's)",
    )  # fmt: skip
    parser.add_argument(
        "--cpus-per-trial", type=positive, default=1.0, help="CPUs each trial's Ray task asks for"
    )
    parser.add_argument(
        "--no-ray", action="store_true", help="run the trials one after another in this process"
    )
    parser.add_argument("--force", action="store_true", help="run unchanged trials again")
    parser.add_argument(
        "--dry-run", action="store_true", help="list the trials and their rmpl run commands only"
    )
    from rmpl.project.options import add_run_options

    add_run_options(parser.add_argument_group(
        "rmpl run options", "over every trial's rmpl.toml (see rmpl run --help)"
    ))  # fmt: skip
    parser.set_defaults(run=run)


def _dry_run(plans) -> int:
    import shlex

    for p in plans:
        state = "excluded" if p.excluded else p.problem or shlex.join(["rmpl", *p.argv])
        print(f"{p.name}: {state}")
        for note in p.notes:
            print(f"  {note}")
    return 0


def run(args: argparse.Namespace) -> int:
    from rmpl.project import batch_exit_code
    from rmpl.project.execute import FAILED, run_plans
    from rmpl.project.options import given_run_options
    from rmpl.project.plan import plan_project
    from rmpl.project.summary import write_summary

    project = Path(args.project)
    out = Path(args.out) if args.out else project / "rmpl-out"
    plans = plan_project(project, out, given_run_options(args))
    if args.dry_run:
        return _dry_run(plans)
    ray_only = [o for o, v in [("--address", args.address), ("--workers", args.workers),
                               ("--cpus-per-trial", args.cpus_per_trial != 1.0)] if v]  # fmt: skip
    if args.no_ray and ray_only:
        log.warning("WARNING: %s not used: --no-ray runs the trials one after another here",
                    ", ".join(ray_only))  # fmt: skip
    for p in plans:
        for note in p.notes:
            log.info("%s: %s", p.name, note)
    results = run_plans(
        plans, out / "logs", ray=not args.no_ray, address=args.address, workers=args.workers,
        cpus_per_trial=args.cpus_per_trial, force=args.force,
    )  # fmt: skip
    paths = write_summary(results, out, project)
    failed = [r for r in results if r.status == FAILED]
    for r in failed:
        print(f"rmpl batch: trial {r.plan.name} failed: {r.error}", file=sys.stderr)
    counts = {
        s: sum(r.status == s for r in results) for s in dict.fromkeys(r.status for r in results)
    }
    log.info("%d trials: %s; summary: %s", len(results),
             ", ".join(f"{n} {s}" for s, n in counts.items()), paths[0])  # fmt: skip
    return batch_exit_code(results)
