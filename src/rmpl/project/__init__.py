"""Whole projects: many trials, one command, on Ray (``rmpl batch``).

A project is a folder of trials in Pose2Sim's layout or rmpl's own
(:mod:`rmpl.project.layout`); each trial's ``rmpl run`` options come from ``rmpl.toml``
files, Pose2Sim's ``Config.toml`` and the command line (:mod:`rmpl.project.options`);
:mod:`rmpl.project.plan` turns each trial into an ``rmpl run`` command line and a
fingerprint; :mod:`rmpl.project.execute` runs them as Ray tasks (a trial whose inputs and
options have not changed is skipped; a failed one is reported and the others go on);
:mod:`rmpl.project.summary` writes ``summary.md`` / ``.json`` / ``.html``.
:mod:`rmpl.project.unused` names the ``rmpl run`` options the chosen path does not use.

>>> from rmpl.project import run_project  # doctest: +SKIP
>>> results = run_project("session/", "session_out/")  # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["batch_exit_code", "run_project"]


def run_project(project, out, command_line: list[str] | None = None, **run_options):
    """Plan, run and summarise a project; returns the :class:`~rmpl.project.execute.TrialResult`
    of every trial. ``command_line``: ``rmpl run`` options over every trial's
    configuration; ``run_options`` go to :func:`rmpl.project.execute.run_plans` (``ray``,
    ``address``, ``workers``, ``cpus_per_trial``, ``force``, ``progress``)."""
    from rmpl.project.execute import run_plans
    from rmpl.project.options import parse_command_line
    from rmpl.project.plan import plan_project
    from rmpl.project.summary import write_summary

    out = Path(out)
    plans = plan_project(project, out, parse_command_line(command_line or []))
    results = run_plans(plans, out / "logs", **run_options)
    write_summary(results, out, Path(project))
    return results


def batch_exit_code(results) -> int:
    """0: every trial done (or unchanged, or excluded); 1: some trial failed (the others
    completed); 3: none failed, but a person's views disagree in most frames in some trial."""
    from rmpl.project.execute import DISAGREE, FAILED

    statuses = {r.status for r in results}
    if FAILED in statuses:
        return 1
    if DISAGREE in statuses or any(r.exit_code == 3 for r in results):
        return 3
    return 0
