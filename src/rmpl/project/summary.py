"""A project's summary: ``OUT/summary.md``, ``summary.json`` and ``summary.html``.

One row per trial, read from its ``report.json`` (:mod:`rmpl.pipeline.report`): its status,
people, frames, reprojection error (the median over joints of the per-joint medians, as
``rmpl run`` logs it), the view check, each person's estimated height (beside the heights a
Pose2Sim Config.toml gives), the time taken, and links to its report and viewer. A failed
trial has its one line.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from rmpl.project.execute import TrialResult

__all__ = ["summary_rows", "write_summary"]


def _reprojection(report: dict) -> tuple[float | None, float | None]:
    px = [
        j["reprojection_px_median"]
        for j in report.get("joints", [])
        if j.get("reprojection_px_median")
    ]
    mm = [
        j["reprojection_mm_median"]
        for j in report.get("joints", [])
        if j.get("reprojection_mm_median")
    ]
    return (
        round(float(np.median(px)), 2) if px else None,
        round(float(np.median(mm)), 1) if mm else None,
    )


def _view_check(report: dict) -> str:
    check = report.get("check") or {}
    if not check.get("done"):
        return "not checked"
    if report.get("failed_people"):
        who = ", ".join(map(str, report["failed_people"]))
        return f"FAILED: the views disagree on person {who} in most frames"
    rows = report.get("disagreements") or []
    if rows:
        parts = [f"person {r['person']} {r['camera']} {r['frames']} frames" for r in rows[:4]]
        return "some views disagree: " + "; ".join(parts) + (" ..." if len(rows) > 4 else "")
    return "all views agree"


def _link(out: Path, trial_out: Path, name: str) -> str | None:
    p = trial_out / name
    return p.relative_to(out).as_posix() if p.is_file() else None


def summary_rows(results: list[TrialResult], out: Path) -> list[dict]:
    """One dict per trial (plain numbers and text), in the plans' order."""
    rows = []
    for r in results:
        report = r.report or {}
        people = report.get("people", [])
        px, mm = _reprojection(report) if report else (None, None)
        settings = r.plan.settings
        rows.append({
            "trial": r.plan.name,
            "status": r.status,
            "exit_code": r.exit_code,
            "error": r.error,
            "people": len(people) if report else None,
            "frames": (report.get("frames") or {}).get("count") if report else None,
            "fps": report.get("fps") if report else None,
            "reprojection_px": px,
            "reprojection_mm": mm,
            "view_check": _view_check(report) if report else None,
            "heights_m": [p.get("height_m") for p in people] if report else None,
            "given_heights_m": settings.heights,
            "given_masses_kg": settings.masses,
            "seconds": None if r.seconds is None else round(r.seconds, 1),
            "report": _link(out, r.plan.out, "report.md"),
            "viewer": _link(out, r.plan.out, "viewer.html"),
            "log": r.log.relative_to(out).as_posix() if r.log and r.log.is_file() else None,
            "notes": r.plan.notes,
        })  # fmt: skip
    return rows


def _cell(value, spec: str = "g") -> str:
    if value is None:
        return "-"
    if isinstance(value, list):
        return ", ".join("-" if v is None else format(v, spec) for v in value) or "-"
    return str(value)


def _markdown(rows: list[dict], title: str) -> str:
    head = ["trial", "status", "people", "frames", "reprojection px (mm)", "view check",
            "heights m (given)", "time s", "report", "viewer"]  # fmt: skip
    lines = [f"# {title}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        rep = (
            "-"
            if r["reprojection_px"] is None
            else f"{r['reprojection_px']:.1f} ({_cell(r['reprojection_mm'])})"
        )
        heights = _cell(r["heights_m"], ".2f") + (
            f" ({_cell(r['given_heights_m'])})" if r["given_heights_m"] else ""
        )
        cells = [r["trial"], r["status"], _cell(r["people"]), _cell(r["frames"]), rep,
                 _cell(r["view_check"]), heights, _cell(r["seconds"]),
                 f"[report]({r['report']})" if r["report"] else "-",
                 f"[viewer]({r['viewer']})" if r["viewer"] else "-"]  # fmt: skip
        lines.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    failed = [r for r in rows if r["error"]]
    if failed:
        lines += ["", "## Failed", ""]
        lines += [
            f"- **{r['trial']}**: {r['error']}" + (f" ([log]({r['log']}))" if r["log"] else "")
            for r in failed
        ]
    notes = [r for r in rows if r["notes"]]
    if notes:
        lines += ["", "## Notes", ""]
        lines += [f"- **{r['trial']}**: " + "; ".join(r["notes"]) for r in notes]
    return "\n".join(lines) + "\n"


def _html(rows: list[dict], title: str) -> str:
    head = ["trial", "status", "people", "frames", "reprojection px", "mm", "view check",
            "heights m", "given m", "time s", "links", "error"]  # fmt: skip
    body = []
    for r in rows:
        links = " ".join(
            f'<a href="{html.escape(r[k])}">{k}</a>' for k in ("report", "viewer", "log") if r[k]
        )
        keys = ["trial", "status", "people", "frames", "reprojection_px", "reprojection_mm",
                "view_check", "heights_m", "given_heights_m", "seconds"]  # fmt: skip
        cells = [_cell(r[k], ".2f" if k == "heights_m" else "g") for k in keys]
        tds = "".join(f"<td>{html.escape(c)}</td>" for c in cells)
        bad = ' class="bad"' if r["status"] == "failed" else ""
        body.append(f"<tr{bad}>{tds}<td>{links}</td><td>{html.escape(r['error'] or '')}</td></tr>")
    ths = "".join(f"<th>{h}</th>" for h in head)
    style = ("body{font-family:sans-serif}table{border-collapse:collapse}"
             "td,th{border:1px solid #ccc;padding:3px 6px}tr.bad{background:#fdd}")  # fmt: skip
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{style}</style></head><body><h1>{html.escape(title)}</h1><table><tr>{ths}</tr>"
            + "".join(body) + "</table></body></html>\n")  # fmt: skip


def write_summary(results: list[TrialResult], out: Path, project: Path) -> list[Path]:
    """Write ``summary.md``, ``summary.json`` and ``summary.html`` into ``out`` (each file
    atomically); returns their paths."""
    from rmpl import __version__
    from rmpl.io.atomic import atomic_path

    rows = summary_rows(results, out)
    title = f"rmpl batch: {project.resolve().name}"
    doc = {"format": "rmpl.batch-summary", "version": 1, "rmpl": __version__,
           "project": str(project), "trials": rows}  # fmt: skip
    texts = {"summary.md": _markdown(rows, title), "summary.json": json.dumps(doc, indent=1),
             "summary.html": _html(rows, title)}  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, text in texts.items():
        with atomic_path(out / name) as tmp:
            tmp.write_text(text, encoding="utf-8")
        paths.append(out / name)
    return paths
