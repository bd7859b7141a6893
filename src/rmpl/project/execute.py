"""Run a project's trials: each one ``rmpl run`` (its own code path), as a Ray task.

:func:`run_trial` is one trial: ``rmpl.cli.main(["run", ...])`` with the trial's argv, its
log (and any progress bar) in ``OUT/logs/<trial>.log``, then, when the run finished (exit 0,
or 3: a person's views disagree, outputs written), ``OUT/<trial>/trial.json`` with the
fingerprint, the time taken and the exit status. ``rmpl run`` writes the trial's folder as a
unit (:func:`rmpl.io.atomic.staged_folder`), so a failed or killed trial leaves its previous
complete set, and nothing of another trial.

:func:`run_plans` runs the trials that are not unchanged: on Ray (a local Ray started for the
run, or a running cluster with ``address``), each trial one task asking ``cpus_per_trial``
CPUs, at most ``workers`` at once; or with ``ray=False`` one after another in this process.
One progress bar for the whole project; a line per finished trial. A failed trial (bad
input, an error, a lost worker) is reported and the others go on.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from rmpl.errors import InputError
from rmpl.project.plan import STAMP, TrialPlan, unchanged

__all__ = ["TrialResult", "run_plans", "run_trial"]

log = logging.getLogger(__name__)

DONE, DISAGREE, SKIPPED, FAILED, EXCLUDED = (
    "done",
    "done, views disagree",
    "unchanged",
    "failed",
    "excluded",
)


@dataclass
class TrialResult:
    """How a trial went: ``status`` one of done / done, views disagree / unchanged (skipped)
    / failed / excluded; ``error`` its one line when failed; ``seconds`` the run's wall time
    (of the recorded run when unchanged); ``report`` its report.json (None without)."""

    plan: TrialPlan
    status: str
    exit_code: int | None = None
    error: str | None = None
    seconds: float | None = None
    report: dict | None = None
    log: Path | None = None


_ERROR = re.compile(r"^rmpl(?: run)?: error: (.*)$")


class _Tee:
    """A text stream that writes to a file and keeps ``rmpl``'s error line."""

    def __init__(self, stream):
        self.stream, self.error = stream, None

    def write(self, text: str) -> int:
        for line in text.splitlines():
            if m := _ERROR.match(line):
                self.error = m.group(1)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:
        return False


def _read_report(out: Path) -> dict | None:
    try:
        return json.loads((out / "report.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _write_stamp(out: Path, record: dict) -> None:
    from rmpl.io.atomic import atomic_path

    with atomic_path(out / STAMP) as tmp:
        tmp.write_text(json.dumps(record, indent=1), encoding="utf-8")


def run_trial(argv: list[str], log_path: str, stamp: dict) -> dict:
    """One trial through ``rmpl run``; the log in ``log_path``. Returns exit_code, error,
    seconds and report (report.json, or None). Runs in a Ray worker or in this process."""
    from rmpl.cli import main

    out = Path(argv[argv.index("--out") + 1])
    Path(log_path).parent.mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    start = time.perf_counter()
    with open(log_path, "w", encoding="utf-8") as f:
        err = _Tee(f)
        handler = logging.StreamHandler(f)
        handler.setFormatter(logging.Formatter("%(message)s"))
        level, others = root.level, list(root.handlers)
        for h in others:  # the trial's log goes to its file only
            root.removeHandler(h)
        root.setLevel(logging.INFO)
        root.addHandler(handler)
        try:
            with contextlib.redirect_stdout(f), contextlib.redirect_stderr(err):
                code = main(argv)
        except SystemExit as e:  # argparse refused an option (usage on the log)
            code = e.code if isinstance(e.code, int) else 2
        except Exception as e:  # an error rmpl run did not expect: this trial fails, not the batch
            code, err.error = 1, f"{type(e).__name__}: {e} (see {log_path})"
            log.debug("trial failed", exc_info=True)
            import traceback

            traceback.print_exc(file=f)
        finally:
            root.removeHandler(handler)
            for h in others:
                root.addHandler(h)
            root.setLevel(level)
    seconds = time.perf_counter() - start
    if code != 0 and code != 3 and err.error is None:
        err.error = f"rmpl run exited with status {code} (see {log_path})"
    report = _read_report(out) if code in (0, 3) else None
    if code in (0, 3):
        _write_stamp(out, {**stamp, "exit_code": code, "seconds": round(seconds, 2)})
    return {"exit_code": code, "error": err.error, "seconds": seconds, "report": report}


def _result(plan: TrialPlan, answer: dict, log_path: Path) -> TrialResult:
    code = answer["exit_code"]
    status = DONE if code == 0 else DISAGREE if code == 3 else FAILED
    return TrialResult(plan, status, code, answer["error"], answer["seconds"], answer["report"],
                       log_path)  # fmt: skip


def _stamp(plan: TrialPlan) -> dict:
    from rmpl import __version__

    return {"format": "rmpl.trial", "version": 1, "trial": plan.name, "rmpl": __version__,
            "fingerprint": plan.fingerprint, "argv": plan.argv}  # fmt: skip


def _say(bar, result: TrialResult) -> None:
    t = "" if result.seconds is None else f" in {result.seconds:.1f} s"
    if result.status == SKIPPED:
        t = "" if result.seconds is None else f" (its last run took {result.seconds:.1f} s)"
    line = f"{result.plan.name}: {result.status}{t}"
    if result.error:
        line += f": {result.error}"
    bar.write(line, file=sys.stderr)


def _settled(plans: list[TrialPlan], force: bool) -> tuple[list[TrialResult], list[TrialPlan]]:
    """The results known without running (excluded, cannot run, unchanged) and the rest."""
    known, todo = [], []
    for plan in plans:
        if plan.excluded:
            known.append(TrialResult(plan, EXCLUDED))
        elif plan.problem is not None:
            known.append(TrialResult(plan, FAILED, 2, plan.problem))
        elif not force and (stamp := unchanged(plan)) is not None:
            known.append(TrialResult(plan, SKIPPED, stamp.get("exit_code"), None,
                                     stamp.get("seconds"), _read_report(plan.out)))  # fmt: skip
        else:
            todo.append(plan)
    return known, todo


def run_plans(
    plans: list[TrialPlan],
    logs: Path,
    *,
    ray: bool = True,
    address: str | None = None,
    workers: int | None = None,
    cpus_per_trial: float = 1.0,
    force: bool = False,
    progress: bool = True,
) -> list[TrialResult]:
    """Run every trial that is not excluded, unchanged or unable to run; results in the
    plans' order.

    Args:
        logs: the folder of the trials' logs (``<trial>.log``).
        ray: run on Ray (False: one after another in this process).
        address: a running Ray cluster to join (``ray start --head`` prints it); None
            starts a local Ray for the run.
        workers: at most this many trials at once (default: the CPUs of the local Ray /
            the cluster, divided by ``cpus_per_trial``).
        cpus_per_trial: the CPUs each trial's task asks Ray for.
        force: run unchanged trials too.
    """
    from tqdm import tqdm

    known, todo = _settled(plans, force)
    bar = tqdm(total=len(plans), desc="trials", unit="trial", disable=not progress,
               file=sys.stderr)  # fmt: skip
    for r in known:
        bar.update(1)
        _say(bar, r)
    done = {id(r.plan): r for r in known}
    jobs = [(p, logs / f"{p.name.replace('/', '__')}.log") for p in todo]
    if jobs and ray:
        answers = _on_ray(jobs, bar, address, workers, cpus_per_trial)
    else:
        answers = _inline(jobs, bar)
    done.update({id(r.plan): r for r in answers})
    bar.close()
    return [done[id(p)] for p in plans]


def _inline(jobs, bar) -> list[TrialResult]:
    results = []
    for plan, log_path in jobs:
        bar.set_postfix_str(plan.name)
        r = _result(plan, run_trial(plan.argv, str(log_path), _stamp(plan)), log_path)
        results.append(r)
        bar.update(1)
        _say(bar, r)
    return results


def _start_ray(address: str | None, workers: int | None, cpus_per_trial: float):
    """Ray, connected: the running instance of this process, the cluster at ``address``, or
    a local Ray started here. Returns (the ray module, whether this call started it)."""
    try:
        import ray
    except ModuleNotFoundError:
        raise InputError(None, "--address" if address else None, "Ray installed to run trials "
                         "as Ray tasks: pip install 'rmpl[ray]' (or give --no-ray)",
                         "no module ray") from None  # fmt: skip
    if ray.is_initialized():
        return ray, False
    if address:
        ray.init(address=address, log_to_driver=False)
    else:
        cpus = (workers or os.cpu_count() or 1) * cpus_per_trial
        ray.init(
            address="local",
            num_cpus=max(1, round(cpus)),
            include_dashboard=False,
            log_to_driver=False,
        )  # fmt: skip (a new local Ray, not one running here)
    return ray, True


def _runtime_env() -> dict:
    """The tasks' environment: rmpl imported from where this process imports it (when that
    path exists on the worker's machine), before the worker's own PYTHONPATH."""
    import rmpl

    here = str(Path(rmpl.__file__).resolve().parents[1])
    given = [os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    path = os.pathsep.join(dict.fromkeys([here, *given]))
    return {"env_vars": {"PYTHONPATH": path}}


def _on_ray(jobs, bar, address, workers, cpus_per_trial) -> list[TrialResult]:
    ray, started = _start_ray(address, workers, cpus_per_trial)
    try:
        options = {"num_cpus": cpus_per_trial, "max_retries": 0}
        if address:  # a local Ray's workers have this process' environment already
            options["runtime_env"] = _runtime_env()
        task = ray.remote(**options)(run_trial)
        if workers is None:
            workers = max(1, int(ray.cluster_resources().get("CPU", 1) // cpus_per_trial))
        log.info("Ray: %d trials, at most %d at once, %g CPU each (%s)", len(jobs), workers,
                 cpus_per_trial, address or "local")  # fmt: skip
        waiting, running, results = list(jobs), {}, []
        while waiting or running:
            while waiting and len(running) < workers:
                plan, log_path = waiting.pop(0)
                ref = task.remote(plan.argv, str(log_path), _stamp(plan))
                running[ref] = (plan, log_path)
            bar.set_postfix_str(", ".join(p.name for p, _ in running.values())[:60])
            ready, _ = ray.wait(list(running), num_returns=1)
            plan, log_path = running.pop(ready[0])
            try:
                r = _result(plan, ray.get(ready[0]), log_path)
            except Exception as e:  # a lost worker, a task that could not start
                r = TrialResult(plan, FAILED, None, f"Ray task failed: {type(e).__name__}: "
                                f"{str(e).splitlines()[0] if str(e) else ''}")  # fmt: skip
            results.append(r)
            bar.update(1)
            _say(bar, r)
        return results
    finally:
        if started:
            ray.shutdown()
