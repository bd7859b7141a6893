"""Each trial's ``rmpl run`` command line, output folder and fingerprint.

:func:`plan_project` finds the trials (:func:`rmpl.project.layout.find_trials`), reads their
configuration (:mod:`rmpl.project.options`) and gives each a :class:`TrialPlan`: the argv of
``rmpl run`` (its own parser checked it), the output folder ``OUT/<trial>/``, and a
fingerprint of everything the result depends on (rmpl's version, the options, and the
names, sizes and modification times of every input file, calibration and configuration
file). A trial that cannot run (no inputs, no calibration, an unreadable configuration, an
unknown key) has one line in ``problem`` and nothing else of it is done.

A trial whose ``OUT/<trial>/trial.json`` holds the same fingerprint and a finished run, with
its ``report.json`` beside it, is unchanged (:func:`unchanged`) and is not run again.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

from rmpl.errors import InputError
from rmpl.project import options as opts
from rmpl.project.layout import Trial, find_trials

__all__ = ["STAMP", "TrialPlan", "fingerprint", "plan_project", "unchanged"]

log = logging.getLogger(__name__)

#: The file in each trial's output folder that records its finished run.
STAMP = "trial.json"


@dataclass
class TrialPlan:
    """What to do with one trial.

    Attributes:
        trial: the trial as found.
        out: its output folder.
        argv: ``rmpl.cli.main``'s argument list (``["run", ...]``), None when it cannot run.
        problem: why it cannot run (one line), or None.
        excluded: skipped by a Pose2Sim ``exclude_from_batch``.
        fingerprint: hex digest of its inputs and options (None when it cannot run).
        settings: what its Pose2Sim ``Config.toml`` files say.
        notes: what was chosen and where it came from.
    """

    trial: Trial
    out: Path
    argv: list[str] | None = None
    problem: str | None = None
    excluded: bool = False
    fingerprint: str | None = None
    settings: opts.Pose2SimSettings = field(default_factory=opts.Pose2SimSettings)
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.trial.name


def _base_options(trial: Trial, settings: opts.Pose2SimSettings) -> opts.Options:
    """What the layout and Pose2Sim's Config.toml give, before any rmpl.toml."""
    base: opts.Options = {}
    if trial.calib is not None:
        base["calib"] = [str(trial.calib)]
    if trial.source is not None:
        base[trial.source] = [str(p) for p in trial.inputs]
    if settings.fps is not None:
        base["fps"] = [f"{settings.fps:g}"]
    return base


def _is_excluded(trial: Trial, settings: opts.Pose2SimSettings) -> bool:
    return any(e in (trial.name, trial.folder.name) for e in settings.excluded)


def _plan(trial: Trial, out_root: Path, command_line: opts.Options) -> TrialPlan:
    plan = TrialPlan(trial, out_root / trial.name)
    plan.notes += trial.notes
    try:
        plan.settings = opts.pose2sim_settings(trial.pose2sim)
        levels = [opts.read_config(p) for p in trial.configs]
    except InputError as e:
        plan.problem = str(e)
        return plan
    plan.notes += plan.settings.notes
    plan.excluded = _is_excluded(trial, plan.settings)
    merged = opts.merge(_base_options(trial, plan.settings), *levels, command_line)
    for key, why in trial.missing.items():
        given = key in merged if key == "calib" else any(s in merged for s in opts.SOURCES)
        if not given:
            plan.problem = why
            return plan
    if (
        "fps" in merged
        and plan.settings.fps is not None
        and merged["fps"] != [f"{plan.settings.fps:g}"]
    ):
        plan.notes.append(f"--fps {merged['fps'][0]} (rmpl.toml or command line) over Config.toml")
    plan.argv = opts.run_argv(merged, plan.out)
    plan.fingerprint = fingerprint(plan.argv, trial.pose2sim + trial.configs)
    return plan


def plan_project(
    root: str | Path, out: str | Path, command_line: opts.Options | None = None
) -> list[TrialPlan]:
    """The plan of every trial of the project at ``root``, writing under ``out``.

    Raises:
        InputError: ``root`` is not a folder, or holds no trial.
    """
    root, out = Path(root), Path(out)
    trials = find_trials(root, skip=[out])
    if not trials:
        raise InputError(root, None, "a project: trial folders with videos, image folders or 2D "
                         "files (Pose2Sim's layout or rmpl's)", "no trial")  # fmt: skip
    names = [t.name for t in trials]
    if len(set(names)) != len(names):  # pragma: no cover (relative paths are distinct)
        raise InputError(root, None, "distinct trial names", names)
    return [_plan(t, out, command_line or {}) for t in trials]


def _stat_tree(path: Path) -> list[tuple[str, int, int]]:
    """(path, size, modification time in ns) of a file, or of every file below a folder."""
    if path.is_file():
        st = path.stat()
        return [(str(path), st.st_size, st.st_mtime_ns)]
    rows = []
    for folder, dirs, files in os.walk(path):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for f in sorted(files):
            if not f.startswith("."):
                p = Path(folder) / f
                st = p.stat()
                rows.append((str(p), st.st_size, st.st_mtime_ns))
    return rows


def fingerprint(argv: list[str], extra_files: list[Path]) -> str:
    """A digest of rmpl's version, ``argv`` (without the output folder) and the names,
    sizes and modification times of every path it names and of ``extra_files``."""
    from rmpl import __version__

    args = list(argv)
    if "--out" in args:
        i = args.index("--out")
        del args[i : i + 2]
    files = []
    for token in args + [str(p) for p in extra_files]:
        p = Path(token)
        if not token.startswith("-") and p.exists():
            files += _stat_tree(p)
    doc = {"rmpl": __version__, "argv": args, "files": sorted(set(files))}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def unchanged(plan: TrialPlan) -> dict | None:
    """The recorded run of an unchanged trial (its ``trial.json``), or None to run it."""
    if plan.fingerprint is None:
        return None
    try:
        stamp = json.loads((plan.out / STAMP).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    same = isinstance(stamp, dict) and stamp.get("fingerprint") == plan.fingerprint
    if same and stamp.get("exit_code") in (0, 3) and (plan.out / "report.json").is_file():
        return stamp
    return None
