"""The synthetic experiments of ``rmpl evaluate --dataset synthetic``, as reports.

- **random cameras** (or MHP renders): MPJPE and friends per number of views, keypoint
  dropout and calibration noise (:func:`rmpl.evaluate.synthetic.evaluate_synthetic`);
- **sphere**: two cameras on a sphere, the angle between them swept per camera height
  (:func:`rmpl.evaluate.synthetic.evaluate_sphere`).

Each returns a :class:`rmpl.evaluate.tables.Report`: results.md (a header saying what was
simulated, then the tables), results.csv, per_joint.csv and the figures.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.evaluate.harness import EvalConfig
from rmpl.evaluate.methods import Method
from rmpl.evaluate.options import parse_floats
from rmpl.evaluate.tables import Report, markdown_table

__all__ = ["SyntheticOptions", "run_synthetic", "synthetic_view_counts"]

SCORE_COLUMNS = ["mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage", "mpjpe_common"]


@dataclass(frozen=True)
class SyntheticOptions:
    """The options of a synthetic run (``rmpl evaluate --dataset synthetic``).

    Attributes:
        root: a pose bank .npz, a motion folder, or an MHP directory (``rmpl generate``).
        cameras: "random" or "sphere" (None: random).
        views: view counts, e.g. "1,2,3,4,5" (None: 1-5); not with "sphere".
        samples: scenes per view count and condition (or per sphere point).
        holdout: held-out subjects of a pose bank, comma-separated.
        heights, angles: sphere: camera heights (m) and angles between the cameras (deg).
        radius: sphere radius, metres.
        pck_mm: PCK threshold, millimetres (as given, for the table titles).
        keypoints: 2D files (refused: the 2D is simulated).
    """

    root: str
    cameras: str | None = None
    views: str | None = None
    samples: int = 2000
    holdout: str = "03"
    heights: str = "2.2,3.2,4"
    angles: str = ",".join(str(a) for a in range(10, 181, 10))
    radius: float = 6.0
    pck_mm: float = 150.0
    keypoints: list[str] | None = None


def synthetic_view_counts(spec: str | None) -> list[int]:
    """``--views`` for synthetic: view counts >= 1 ("pairs" = 2); None: 1-5."""
    if spec is None:
        return [1, 2, 3, 4, 5]
    counts = []
    for item in spec.split(","):
        item = item.strip()
        if item == "pairs":
            item = "2"
        if not item.isdigit() or int(item) < 1:
            raise InputError(None, "--views", "view counts >= 1 (or 'pairs') for synthetic", item)
        counts.append(int(item))
    return counts


def _mhp_root(root: str) -> Path | None:
    """``root`` when it is an MHP directory (a manifest.json beside shards), else None."""
    p = Path(root)
    return p if (p / "manifest.json").is_file() else None


def _mhp_header(opts: SyntheticOptions, shards: Path, command: str, seed: int) -> list[str]:
    meta = json.loads((shards / "manifest.json").read_text())
    counts = meta.get("counts", {})
    return [
        "# rmpl evaluate: synthetic (MHP renders)",
        "",
        f"`{command}`",
        "",
        f"- scenes: MHP directory {opts.root} ({counts.get('meshes', '?')} meshes x "
        f"{counts.get('views', '?')} views; its subjects: "
        f"{', '.join(meta.get('pose_bank', {}).get('subjects', {})) or '?'}); each "
        "scene is one mesh seen by V of its views drawn at random",
        f"- 2D: the real detector's output on the renders ({meta.get('detector', '?')}), "
        f"seed {seed}; every method gets the same 2D",
        "- scored joints: all 17 COCO joints regressed from the mesh; KP*: the 12 limb "
        f"joints; PCK threshold {opts.pck_mm:g} mm (a missing joint is wrong)",
    ]


def _bank_header(opts: SyntheticOptions, mode: str, held, command: str, seed: int) -> list[str]:
    return [
        f"# rmpl evaluate: synthetic ({mode} cameras)",
        "",
        f"`{command}`",
        "",
        f"- poses: {len(held)} held-out poses of subjects {opts.holdout} from {opts.root}",
        "- 2D: the parametric detector noise model (rmpl.synth.noise defaults), seed "
        f"{seed}; every method gets the same 2D",
        "- scored joints: all 17 COCO joints; KP*: the 12 limb joints; PCK threshold "
        f"{opts.pck_mm:g} mm (a missing joint is wrong)",
    ]


def _load_bank(path: str):
    """A pose bank: an ``.npz`` written by ``rmpl poses``, or a motion-capture folder."""
    from rmpl.synth.motion import load_motion_dir, load_pose_set

    p = Path(path)
    if p.is_file():
        return load_pose_set(p)
    if p.is_dir():
        return load_motion_dir(p)
    raise FileNotFoundError(f"{path}: pose bank or motion folder not found")


def _held_out_poses(opts: SyntheticOptions):
    bank = _load_bank(opts.root)
    _, held = bank.split(opts.holdout.split(","))
    if not len(held):
        raise ValueError(f"{opts.root}: no poses of held-out subjects {opts.holdout}")
    return held


def run_synthetic(
    opts: SyntheticOptions, methods: dict[str, Method], config: EvalConfig, command: str
) -> Report:
    """The random-camera (or MHP) experiment or the sphere sweep, as a report.

    Args:
        opts: what to simulate.
        methods: name -> method.
        config: dropout, calibration noise and the seed.
        command: the command line that reproduces the run, quoted in results.md.

    Raises:
        InputError: options that do not fit the experiment.
    """
    mode = opts.cameras or "random"
    if mode not in ("random", "sphere"):
        raise InputError(None, "--cameras", "'random' or 'sphere' for synthetic", mode)
    if opts.keypoints:
        raise InputError(None, "--keypoints", "no 2D files for synthetic (2D is simulated)")
    if opts.samples < 1:
        raise InputError(None, "--samples", "a positive number", opts.samples)
    shards = _mhp_root(opts.root)
    if shards is not None:
        if mode == "sphere":
            raise InputError(
                opts.root,
                "--cameras sphere",
                "a pose bank (MHP renders have their own cameras)",
                "an MHP directory",
            )
        head, poses = _mhp_header(opts, shards, command, config.seed), None
    else:
        held = _held_out_poses(opts)
        head, poses = _bank_header(opts, mode, held, command, config.seed), held.poses
    if mode == "sphere":
        return _sphere(opts, config, poses, methods, head)
    return _random_cameras(opts, config, poses, shards, methods, head)


# --------------------------------------------------------------------------- random cameras


def _condition_notes(opts: SyntheticOptions, config: EvalConfig, shards) -> list[str]:
    if shards is None:
        notes = [
            f"- scenes: {opts.samples} per view count and condition, random camera setups "
            "(preset 'universal'), the person anywhere in a 4 x 4 m room"
        ]
    else:
        notes = [f"- {opts.samples} scenes per view count and condition"]
    if config.calib_noise:
        notes.append(
            f"- calibration noise {config.calib_noise[0]:g} deg / "
            f"{1000 * config.calib_noise[1]:g} mm on the methods' extrinsics, "
            f"{config.calib_reps} draws"
        )
    return notes


def _joint_breakdown(preds: dict, config: EvalConfig) -> tuple[list[dict], dict]:
    """Per-joint rows of every condition, and the clean condition's per-joint errors (mm).

    Args:
        preds: (views, dropout, calib, method) -> (pred, target), each (B, 17, 3) metres.

    Returns:
        per_joint.csv rows, and view label -> method -> joint -> finite errors (mm).
    """
    from rmpl.evaluate.scoring import pose_metrics
    from rmpl.skeleton import COCO17

    rows, errors = [], {}
    for (v, p, calib, m), (pred, target) in preds.items():
        for j in range(17):
            r = pose_metrics(pred, target, [j], config.pck_threshold)
            rows.append(
                {
                    "views": v,
                    "method": m,
                    "joint": COCO17.joints[j],
                    "mpjpe": r["mpjpe"],
                    "coverage": r["coverage"],
                    "pck": r["pck"],
                    "dropout": p,
                    "calib_noise": "none" if calib is None else "noisy",
                }
            )
        if p == config.dropout[0] and calib is None:
            e = np.linalg.norm(pred - target, axis=-1) * 1000
            errors.setdefault(f"{v} views", {})[m] = {
                COCO17.joints[j]: e[:, j][np.isfinite(e[:, j])] for j in range(17)
            }
    return rows, errors


def _random_cameras(opts, config: EvalConfig, poses, shards, methods, head) -> Report:
    from rmpl.evaluate.plots import synthetic_plots
    from rmpl.evaluate.synthetic import evaluate_synthetic

    counts = synthetic_view_counts(opts.views)
    preds: dict = {}
    rows = evaluate_synthetic(
        poses,
        methods,
        counts,
        opts.samples,
        seed=config.seed,
        dropout=config.dropout,
        calib_noise=config.calib_noise,
        calib_reps=config.calib_reps if config.calib_noise else 1,
        pck_threshold=config.pck_threshold,
        predictions=preds,
        shards=shards,
    )
    head = head + _condition_notes(opts, config, shards)
    cols = ["views", "method", *SCORE_COLUMNS]
    if len(config.dropout) > 1:
        cols.append("dropout")
    if config.calib_noise:
        cols.append("calib_noise")
    text = "\n".join(head) + "\n\n" + markdown_table(rows, cols, opts.pck_mm)
    joint_rows, errors = _joint_breakdown(preds, config)
    return Report(
        text,
        {"results.md": text, "results.csv": rows, "per_joint.csv": joint_rows},
        lambda out: synthetic_plots(out, rows, errors, config.dropout),
        log_files=False,
    )


# --------------------------------------------------------------------------- sphere


def _by_angle(rows, heights, angles, methods, key: str) -> list[str]:
    """A Markdown table of ``key`` (mm): one row per angle, one column per height and method."""
    cols = [(h, m) for h in heights for m in methods]
    lines = [
        "| angle (deg) | " + " | ".join(f"{m} @ {h:g} m" for h, m in cols) + " |",
        "|---:|" + "---:|" * len(cols),
    ]
    for a in angles:
        cells = []
        for h, m in cols:
            r = next(x for x in rows if x["height"] == h and x["angle"] == a and x["method"] == m)
            cells.append(f"{r[key]:.1f}" if np.isfinite(r[key]) else "—")
        lines.append(f"| {a:g} | " + " | ".join(cells) + " |")
    return lines


def _sphere_text(opts, rows, heights, angles, methods, head) -> str:
    head = head + [
        f"- cameras: two, {opts.radius:g} m from (0, 0, 1 m) (the person's mid-hip is above the "
        "origin) at the given height, azimuths -angle/2 and +angle/2, aimed at (0, 0, 1 m); "
        f"f = 1145 px, 1000 x 1000 px; {opts.samples} scenes per point, the same at every point"
    ]
    text = "\n".join(head) + "\n\n"
    text += markdown_table(rows, ["height", "angle", "method", *SCORE_COLUMNS], opts.pck_mm)
    lines = _by_angle(rows, heights, angles, methods, "mpjpe")
    text += "\nMPJPE (mm) by angle:\n\n" + "\n".join(lines) + "\n"
    lines = _by_angle(rows, heights, angles, methods, "mpjpe_common")
    text += (
        "\nMPJPE (mm) by angle on the joints every method estimated (triangulation needs a "
        "joint in both views):\n\n" + "\n".join(lines) + "\n"
    )
    return text


def _sphere(opts, config: EvalConfig, poses, methods, head) -> Report:
    from rmpl.evaluate.plots import sphere_plots
    from rmpl.evaluate.synthetic import evaluate_sphere

    if opts.views is not None:
        raise InputError(None, "--views", "no --views with --cameras sphere (always 2)", opts.views)
    if len(config.dropout) > 1 or config.dropout[0] > 0 or config.calib_noise:
        raise InputError(None, "--cameras sphere", "no --dropout / --calib-noise in the sweep")
    heights = parse_floats(opts.heights, "--heights")
    angles = parse_floats(opts.angles, "--angles")
    if any(not 0 < a <= 180 for a in angles):
        raise InputError(None, "--angles", "angles in (0, 180] degrees", opts.angles)
    rows = evaluate_sphere(
        poses,
        methods,
        heights,
        angles,
        opts.samples,
        seed=config.seed,
        radius=opts.radius,
        pck_threshold=config.pck_threshold,
    )
    names = list(methods)
    text = _sphere_text(opts, rows, heights, angles, names, head)
    return Report(
        text,
        {"results.md": text, "results.csv": rows},
        lambda out: sphere_plots(out, rows, heights, angles, names, opts.radius),
        log_files=False,
    )
