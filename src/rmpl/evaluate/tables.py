"""Tables of an evaluation: rows (one dict per setting), Markdown and CSV.

Rows hold millimetres and percent; :func:`markdown_table` prints them with one decimal and
an em dash for NaN, :func:`write_csv` with four. :func:`benchmark_files` makes every table
of a real-dataset run (results.md, results.csv, per_joint.csv, per_person.csv or
per_clip.csv) and :func:`write_files` writes them atomically.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.evaluate.evalset import EvalSet
from rmpl.evaluate.harness import Evaluation
from rmpl.evaluate.scoring import (
    PCP_PART_NAMES,
    common_mask,
    condition_label,
    mean_finite,
    pcp_actors,
    pcp_by_actor,
    pcp_parts_by_actor,
    pose_metrics,
    root_metrics,
)
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17, HALPE26

__all__ = [
    "COLUMN_TITLES",
    "Report",
    "save_report",
    "benchmark_files",
    "fmt",
    "header_lines",
    "markdown_table",
    "per_group_rows",
    "per_joint_rows",
    "results_rows",
    "sweep_table",
    "write_csv",
    "write_files",
    "write_text",
]

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------- rows


def _common_mpjpe(ev: Evaluation, label: str, ci: int, entries: list[np.ndarray]) -> float:
    """MPJPE (mm) on the joints every method estimated, averaged over the subsets."""
    common = []
    for k, pred in enumerate(entries):
        mask = common_mask(ev, label, ci, k)[:, ev.joints]
        e = np.linalg.norm(pred[:, ev.joints] - ev.gt[:, ev.joints], axis=-1)
        common.append(1000 * e[mask].mean() if mask.any() else np.nan)
    return mean_finite(common)


#: Column-name prefix of the PCP of each conversion (see
#: :data:`~rmpl.evaluate.scoring.PCP_CONVERSIONS`).
PCP_PREFIX = {"derived": "pcp_", "published": "pcp_lit_", "own": "pcp_own_"}


def _has_own(ev: Evaluation) -> bool:
    """Whether a method output HALPE-26: then the tables have the "own" PCP columns."""
    return HALPE26.name in ev.skeletons.values()


def _conversions(ev: Evaluation) -> dict[str, str]:
    """The PCP conversions of an evaluation -> their column prefixes ("own" only with a
    HALPE-26 method, so COCO-17 tables keep their columns)."""
    return {c: pre for c, pre in PCP_PREFIX.items() if c != "own" or _has_own(ev)}


def _pcp_entries(ev: Evaluation, label: str, ci: int, method: str, conversion: str):
    """What PCP with ``conversion`` scores, per subset entry: COCO-17 (n, 17, 3), or for
    "own" HALPE-26 (n, 26, 3); None when the method has no own head points."""
    entries = ev.preds[label, ci, method]
    if conversion != "own":
        return entries
    if ev.skeletons.get(method) != HALPE26.name:
        return None
    extra = ev.extra[label, ci, method]
    return [np.concatenate([p, x], axis=-2) for p, x in zip(entries, extra, strict=True)]


def _pcp_cells(
    ev: Evaluation, entries: list[np.ndarray] | None, conversion: str = "derived"
) -> dict[str, float]:
    """pcp_actor1.. and pcp_mean (%), averaged over the subsets (prefix pcp_lit_: published,
    pcp_own_: own); NaN when ``entries`` is None."""
    pre = PCP_PREFIX[conversion]
    actors = pcp_actors(ev)
    pcps = [pcp_by_actor(pred, ev.native, ev.person, conversion) for pred in entries or []]
    row = {
        f"{pre}{a.replace(' ', '')}": mean_finite(x.get(a, np.nan) for x in pcps) for a in actors
    }
    row[f"{pre}mean"] = mean_finite(row.values()) if actors else np.nan
    return row


def _one_view(ev: Evaluation) -> bool:
    """Whether a setting has single views: then the rows also hold ``root`` and
    ``height_ratio`` (:func:`~rmpl.evaluate.scoring.root_metrics`)."""
    return any(all(len(s) == 1 for s in subs) for subs in ev.view_sets.values())


def results_rows(ev: Evaluation) -> list[dict]:
    """One row per view setting, condition and method (metrics averaged over subsets).

    With a single-view setting (``--views 1``) every row also has ``root`` (pelvis error,
    mm) and ``height_ratio`` (estimated / true stature proxy), after ``mpjpe_common``.

    The column ``2d_source`` names the methods' 2D input ("detections", "annotations",
    "projection" or "keypoints"; "none" for finished results). On Shelf and Campus the
    PCP with the published conversion (``pcp_lit_actor1``, ..., ``pcp_lit_mean``) follows
    it, at the end, then, when a method outputs HALPE-26, the PCP with the methods' own
    neck and head top (``pcp_own_*``, NaN for COCO-17 methods).
    """
    two_d = "none" if ev.scored else ev.evset.two_d
    rows = []
    conds = ev.config.conditions()
    for label in ev.view_sets:
        for ci, (p, calib) in enumerate(conds):
            for m in ev.methods:
                entries = ev.preds[label, ci, m]
                per = [
                    pose_metrics(pred, ev.gt, ev.joints, ev.config.pck_threshold)
                    for pred in entries
                ]
                row = {"views": label, "method": m}
                row["mpjpe"] = mean_finite(r["mpjpe"] for r in per)
                row["coverage"] = mean_finite(r["coverage"] for r in per)
                for key in ("kpstar", "pa_mpjpe", "pck"):
                    row[key] = mean_finite(r[key] for r in per)
                row["mpjpe_common"] = _common_mpjpe(ev, label, ci, entries)
                if _one_view(ev):
                    roots = [root_metrics(pred, ev.gt) for pred in entries]
                    row["root"] = mean_finite(r["root"] for r in roots)
                    row["height_ratio"] = mean_finite(r["height_ratio"] for r in roots)
                if ev.evset.pcp:
                    row |= _pcp_cells(ev, entries)
                row["dropout"], row["calib_noise"] = condition_label(p, calib)
                row["2d_source"] = two_d
                if ev.evset.pcp:
                    row |= _pcp_cells(ev, entries, "published")
                    if _has_own(ev):
                        row |= _pcp_cells(ev, _pcp_entries(ev, label, ci, m, "own"), "own")
                rows.append(row)
    return rows


def per_joint_rows(ev: Evaluation) -> list[dict]:
    """MPJPE and coverage per joint, view setting, condition and method."""
    rows = []
    for label in ev.view_sets:
        for ci, (p, calib) in enumerate(ev.config.conditions()):
            for m in ev.methods:
                entries = ev.preds[label, ci, m]
                for j in ev.joints:
                    per = [pose_metrics(x, ev.gt, [j], ev.config.pck_threshold) for x in entries]
                    d, c = condition_label(p, calib)
                    rows.append(
                        {
                            "views": label,
                            "method": m,
                            "joint": COCO17.joints[j],
                            "mpjpe": mean_finite(r["mpjpe"] for r in per),
                            "coverage": mean_finite(r["coverage"] for r in per),
                            "pck": mean_finite(r["pck"] for r in per),
                            "dropout": d,
                            "calib_noise": c,
                        }
                    )
    return rows


def _person_pcp_cells(
    ev: Evaluation, key: tuple[str, int, str], sel: np.ndarray, person: str
) -> dict[str, float]:
    """PCP of one person with the published (and own) conversion, then per part with each.

    Keys: ``pcp_lit`` (and ``pcp_own``), then ``pcp_<part>``, ``pcp_lit_<part>`` (and
    ``pcp_own_<part>``) for the parts of :data:`~rmpl.evaluate.scoring.PCP_PART_NAMES`;
    averaged over the subsets of view setting, condition and method ``key``. The own
    columns exist when a method outputs HALPE-26; NaN for COCO-17 methods.
    """
    native, labels = ev.native[sel], ev.person[sel]
    out = {}
    for conversion in ("published", "own")[: 1 + _has_own(ev)]:
        entries = _pcp_entries(ev, *key, conversion) or []
        out[PCP_PREFIX[conversion].rstrip("_")] = mean_finite(
            pcp_by_actor(x[sel], native, labels, conversion).get(person, np.nan) for x in entries
        )
    for conversion, pre in _conversions(ev).items():
        entries = _pcp_entries(ev, *key, conversion) or []
        per = [pcp_parts_by_actor(x[sel], native, labels, conversion)[person] for x in entries]
        out |= {f"{pre}{part}": mean_finite(r[part] for r in per) for part in PCP_PART_NAMES}
    return out


def per_group_rows(ev: Evaluation, by: str) -> list[dict]:
    """Metrics per person ("person") or clip ("clip"), view setting, condition and method.

    On Shelf and Campus a person's row ends with :func:`_person_pcp_cells` (the PCP with
    the published (and own) conversion and the PCP per part).
    """
    groups = ev.person if by == "person" else ev.clip
    rows = []
    for label in ev.view_sets:
        for ci, (p, calib) in enumerate(ev.config.conditions()):
            for m in ev.methods:
                entries = ev.preds[label, ci, m]
                for gname in np.unique(groups):
                    sel = groups == gname
                    per = [
                        pose_metrics(x[sel], ev.gt[sel], ev.joints, ev.config.pck_threshold)
                        for x in entries
                    ]
                    row = {"views": label, "method": m, by: str(gname), "poses": int(sel.sum())}
                    for key in ("mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage"):
                        row[key] = mean_finite(r[key] for r in per)
                    if ev.evset.pcp:
                        row["pcp"] = mean_finite(
                            pcp_by_actor(x[sel], ev.native[sel], ev.person[sel]).get(
                                str(gname), np.nan
                            )
                            if by == "person"
                            else np.nan
                            for x in entries
                        )
                    row["dropout"], row["calib_noise"] = condition_label(p, calib)
                    if ev.evset.pcp and by == "person":
                        row |= _person_pcp_cells(ev, (label, ci, m), sel, str(gname))
                    rows.append(row)
    return rows


# --------------------------------------------------------------------------- text


def fmt(x: float, digits: int = 1) -> str:
    """A table cell: one decimal (or ``digits``), an em dash for NaN."""
    if isinstance(x, str | int | np.integer):
        return str(x)
    return "—" if not np.isfinite(x) else f"{x:.{digits}f}"


#: Columns printed with two decimals (ratios, not millimetres or percent).
TWO_DECIMALS = ("height_ratio",)


COLUMN_TITLES = {
    "views": "views",
    "method": "method",
    "mpjpe": "MPJPE (mm)",
    "coverage": "coverage (%)",
    "kpstar": "KP* MPJPE (mm)",
    "pa_mpjpe": "PA-MPJPE (mm)",
    "pck": "PCK@{pck} (%)",
    "mpjpe_common": "MPJPE common joints (mm)",
    "root": "root error (mm)",
    "height_ratio": "height ratio",
    "pcp_mean": "PCP mean (%)",
    "dropout": "dropout p",
    "calib_noise": "calib. noise",
    "joint": "joint",
    "person": "person",
    "clip": "clip",
    "poses": "poses",
    "pcp": "PCP (%)",
    "pcp_lit": "PCP published (%)",
    "pcp_lit_mean": "PCP mean, published (%)",
    "pcp_own": "PCP own head (%)",
    "pcp_own_mean": "PCP mean, own head (%)",
    "conversion": "neck, head top",
    "head": "head",
    "torso": "torso",
    "right_upper_arm": "R upper arm",
    "right_lower_arm": "R lower arm",
    "left_upper_arm": "L upper arm",
    "left_lower_arm": "L lower arm",
    "right_upper_leg": "R upper leg",
    "right_lower_leg": "R lower leg",
    "left_upper_leg": "L upper leg",
    "left_lower_leg": "L lower leg",
    "height": "camera height (m)",
    "angle": "angle (deg)",
}


def _title(column: str) -> str:
    """The Markdown title of a column (``pcp_actor1`` -> "PCP actor 1 (%)")."""
    if column in COLUMN_TITLES:
        return COLUMN_TITLES[column]
    if column.startswith("pcp_lit_"):
        return f"PCP {column[8:].replace('actor', 'actor ')}, published (%)"
    if column.startswith("pcp_own_"):
        return f"PCP {column[8:].replace('actor', 'actor ')}, own head (%)"
    if column.startswith("pcp_"):
        return f"PCP {column[4:].replace('actor', 'actor ')} (%)"
    return column


def markdown_table(rows: list[dict], columns: list[str], pck_mm: float = 150) -> str:
    """Rows as a Markdown table of the given columns (numbers right-aligned)."""
    titles = [_title(c).replace("{pck}", f"{pck_mm:g}mm") for c in columns]
    text = ["| " + " | ".join(titles) + " |"]
    text.append(
        "|"
        + "|".join(
            "---" if c in ("views", "method", "joint", "person", "clip", "conversion") else "---:"
            for c in columns
        )
        + "|"
    )
    for r in rows:
        cells = [fmt(r.get(c, np.nan), 2 if c in TWO_DECIMALS else 1) for c in columns]
        text.append("| " + " | ".join(cells) + " |")
    return "\n".join(text) + "\n"


def _pcp_header_lines(es: EvalSet, own: bool = False) -> list[str]:
    """How PCP is scored: the convention, the neck and head-top conversions, missing ears."""
    lines = [
        "- PCP: Shelf/Campus convention (a part is correct when the mean of its end-point "
        "errors is at most half its length), ten parts (head, arms, legs, torso to the "
        "mid-hip), actors 1-3; the predicted neck and head top are derived from COCO-17",
        "- PCP, published (pcp_lit_*): the predicted neck and head top as in the "
        "literature's evaluations (coco2shelf3D of the mvpose and VoxelPose code, world z "
        "up; ms = shoulder midpoint, n = nose, ec = ear midpoint, hb = (ms + ec) / 2): "
        "head top = 0.75 (ms + (n - ms) * [0.75, 0.75, 1.5]) + 0.25 (2 ec - hb), "
        "neck = 0.75 (ms + 0.5 (n - ms)) + 0.25 hb",
    ]
    if own:
        lines.append(
            "- PCP, own head (pcp_own_*): the neck and head top the method itself outputs "
            "(HALPE-26 neck and head top, rmpl.skeleton halpe26 -> shelf14), the limbs and "
            "the mid-hip (mean of the hips) as above; — for methods that output COCO-17"
        )
    ears = [COCO17.index("left_ear"), COCO17.index("right_ear")]
    if not any((p.scores[..., ears] > 0).any() for p in es.parts):
        lines.append(
            "- the 2D has no ears, so the predicted neck and head top (derived from them) "
            "are missing: the head and torso parts count as wrong (PCP at most 80%)"
        )
    return lines


def header_lines(ev: Evaluation) -> list[str]:
    """What was evaluated and how: dataset, 2D source, protocol, joints, perturbations."""
    es, cfg = ev.evset, ev.config
    frames = sum(len(p) for p in es.parts)
    lines = [
        f"- dataset: {es.name} ({', '.join(p.name for p in es.parts)}; {frames} frames, "
        f"{es.num_views} cameras, {len(ev.gt)} annotated poses)",
        f"- {es.source}",
        f"- scored: {ev.scored}" if ev.scored else f"- association protocol: {es.protocol_text}",
        "- scored joints (COCO-17 names the ground truth defines): "
        + ", ".join(COCO17.joints[j] for j in ev.joints),
        f"- PCK threshold {1000 * cfg.pck_threshold:g} mm (a missing joint is wrong); "
        "MPJPE / PA-MPJPE leave missing joints out (see coverage); metrics are averaged "
        "over the view subsets of a setting",
    ]
    if es.pcp:
        lines += _pcp_header_lines(es, _has_own(ev))
    med, p90, n = ev.reprojection
    if n:
        lines.append(
            f"- ground truth projected onto the 2D input: median {med:.1f} px, 90th percentile "
            f"{p90:.1f} px over {n} person-views (nearest 2D person)"
        )
    if any(p > 0 for p in cfg.dropout):
        lines.append(
            "- keypoint dropout: each keypoint of the per-person input removed with "
            f"probability p (after association), seed {cfg.seed}"
        )
    if cfg.calib_noise is not None:
        deg, m = cfg.calib_noise
        lines.append(
            f"- calibration noise: extrinsics rotated by N(0, {deg:g} deg) and camera centres "
            f"moved by N(0, {1000 * m:g} mm) per camera, given to the methods (association "
            f"uses the true rig); mean of {cfg.calib_reps} draws, seed {cfg.seed}"
        )
    lines += [f"- {n}" for n in es.notes]
    return lines


def write_csv(path: Path, rows: list[dict]) -> None:
    """Rows to CSV atomically (the union of their keys, in first-seen order)."""
    import csv
    import io

    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=keys)
    writer.writeheader()
    for r in rows:
        writer.writerow({k: (f"{v:.4f}" if isinstance(v, float) else v) for k, v in r.items()})
    with atomic_path(path) as tmp:
        tmp.write_text(buf.getvalue())


def write_text(path: Path, text: str) -> None:
    """Text to a file atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_files(out: Path, files: dict[str, object]) -> None:
    """File name -> text (str), JSON (dict) or CSV rows (list of dicts), into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    for name, content in files.items():
        if isinstance(content, str):
            write_text(out / name, content)
        elif isinstance(content, dict):
            write_text(out / name, json.dumps(content, indent=1, default=float))
        else:
            write_csv(out / name, content)


@dataclass
class Report:
    """What one ``rmpl evaluate`` run shows and writes.

    Attributes:
        text: results.md, also what the command prints.
        files: file name -> text (str), JSON (dict) or CSV rows (list of dicts).
        plot: draws the figures into a folder, or None.
        log_files: log "wrote ... into ..." once the files are written.
    """

    text: str
    files: dict[str, object] = field(default_factory=dict)
    plot: Callable[[Path], None] | None = None
    log_files: bool = True


def save_report(out: Path, report: Report, plots: bool = True) -> None:
    """Write a report's files into ``out`` (atomically, each), then its figures."""
    write_files(out, report.files)
    if plots and report.plot is not None:
        report.plot(out)
    if report.log_files:
        log.info("wrote %s into %s", ", ".join(report.files), out)


# --------------------------------------------------------------------------- a benchmark run


def sweep_table(rows: list[dict], dropout: tuple[float, ...], calib_noise) -> str:
    """MPJPE with one column per condition (dropout p / calibration noise)."""
    conds = list(dict.fromkeys((r["dropout"], r["calib_noise"]) for r in rows))
    title = [
        (f"p={d:g}" if len(dropout) > 1 else "")
        + (" " if len(dropout) > 1 and calib_noise else "")
        + (("calib " + c) if calib_noise is not None else "")
        for d, c in conds
    ]
    lines = ["| views | method | " + " | ".join(title) + " |"]
    lines.append("|---|---|" + "---:|" * len(conds))
    for key in dict.fromkeys((r["views"], r["method"]) for r in rows):
        vals = {
            (x["dropout"], x["calib_noise"]): x["mpjpe"]
            for x in rows
            if (x["views"], x["method"]) == key
        }
        cells = [f"{vals[c]:.1f}" if np.isfinite(vals.get(c, np.nan)) else "—" for c in conds]
        lines.append(f"| {key[0]} | {key[1]} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _results_columns(ev: Evaluation, rows: list[dict]) -> list[str]:
    cfg = ev.config
    cols = ["views", "method", "mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage", "mpjpe_common"]
    if _one_view(ev):
        cols += ["root", "height_ratio"]
    if ev.evset.pcp:
        cols += [k for k in rows[0] if k.startswith("pcp_actor")] + ["pcp_mean"]
        cols += [k for k in rows[0] if k.startswith("pcp_lit_actor")] + ["pcp_lit_mean"]
        if _has_own(ev):
            cols += [k for k in rows[0] if k.startswith("pcp_own_actor")] + ["pcp_own_mean"]
    if len(cfg.dropout) > 1:
        cols.insert(2, "dropout")
    if cfg.calib_noise is not None:
        cols.insert(2, "calib_noise")
    return cols


def _group_section(ev: Evaluation, by: str, groups: list[dict]) -> list[str]:
    """The per-person (or per-clip) table of the clean condition, with its title."""
    cfg = ev.config
    clean = [r for r in groups if r["dropout"] == cfg.dropout[0] and r["calib_noise"] == "none"]
    gcols = ["views", "method", by, "poses", "mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage"]
    if ev.evset.pcp and by == "person":
        gcols += ["pcp", "pcp_lit"] + (["pcp_own"] if _has_own(ev) else [])
    title = (
        f"Per {'action/clip' if by == 'clip' else 'person'}"
        f" (dropout {cfg.dropout[0]:g}, no calibration noise):"
    )
    return ["", title, "", markdown_table(clean, gcols, 1000 * cfg.pck_threshold)]


def _clean(ev: Evaluation, rows: list[dict]) -> list[dict]:
    """The rows of the clean condition (the first dropout p, no calibration noise)."""
    p = ev.config.dropout[0]
    return [r for r in rows if r["dropout"] == p and r["calib_noise"] == "none"]


def _pcp_part_section(ev: Evaluation, groups: list[dict]) -> list[str]:
    """The PCP per part and person of the clean condition, each conversion (own: HALPE-26
    methods only), with its title."""
    rows = []
    for r in _clean(ev, groups):
        for conversion, pre in _conversions(ev).items():
            if conversion == "own" and ev.skeletons.get(r["method"]) != HALPE26.name:
                continue
            row = {k: r[k] for k in ("views", "method", "person")} | {"conversion": conversion}
            row |= {part: r[pre + part] for part in PCP_PART_NAMES}
            rows.append(row | {"pcp": r[pre.rstrip("_")]})
    cols = ["views", "method", "person", "conversion", *PCP_PART_NAMES, "pcp"]
    title = (
        f"PCP per part (%, dropout {ev.config.dropout[0]:g}, no calibration noise); neck and "
        "head top derived (rmpl.skeleton) or published (coco2shelf3D)"
        + (", or the method's own (HALPE-26)" if _has_own(ev) else "")
        + ":"
    )
    return ["", title, "", markdown_table(rows, cols)]


def benchmark_files(ev: Evaluation, command: str) -> dict[str, object]:
    """File name -> text or CSV rows: every table of a real-dataset evaluation.

    Args:
        ev: the evaluation.
        command: the command line that reproduces it, quoted in results.md.
    """
    cfg = ev.config
    rows = results_rows(ev)
    text = [f"# rmpl evaluate: {ev.evset.name}", "", f"`{command}`", ""]
    text += header_lines(ev) + [""]
    text.append(markdown_table(rows, _results_columns(ev, rows), 1000 * cfg.pck_threshold))
    if len(cfg.dropout) > 1 or cfg.calib_noise is not None:
        text += ["", "Sweep (MPJPE, mm):", ""]
        text.append(sweep_table(rows, cfg.dropout, cfg.calib_noise))
    by = "clip" if ev.evset.name == "h36m" else "person"
    groups = per_group_rows(ev, by)
    text += _group_section(ev, by, groups)
    if ev.evset.pcp and by == "person":
        text += _pcp_part_section(ev, groups)
    return {
        "results.md": "\n".join(text),
        "results.csv": rows,
        "per_joint.csv": per_joint_rows(ev),
        f"per_{by}.csv": groups,
    }
