"""Compare triangulation, robust triangulation and RMPL on a dataset with 3D ground truth.

Every method gets the same per-person 2D input; tables (results.md, results.csv), per-joint
and per-person/per-clip breakdowns and PNG plots go to --out.

Examples:
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --views 1,2,3,4,5
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --dropout 0,0.2,0.4
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --calib-noise 2,20
  rmpl evaluate --dataset campus --root CAMPUS --2d annotations
  rmpl evaluate --dataset panoptic --root PANOPTIC --keypoints cam00_03.json cam00_06.json ...
  rmpl evaluate --dataset h36m --root H36M --subject S9
  rmpl evaluate --dataset synthetic --root poses.npz --views 1,2,3,4,5 --out results/synth
  rmpl evaluate --dataset synthetic --root poses.npz --cameras sphere --heights 2.2,3.2,4 \\
      --angles 10,20,30,40,50,60,70,80,90,100,110,120,130,140,150,160,170,180
  rmpl evaluate --dataset synthetic --root mhp_val/ --views 2,3,5   (MHP renders, real 2D)
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --poses run/poses.npz \\
      other=pose2sim.trc   (score finished results: rmpl run output, a TRC)
  rmpl evaluate --dataset recording --calib Calib.qca.txt --keypoints pose/cam01_json \\
      pose/cam02_json pose/cam03_json pose/cam04_json --views 1,2,3
      (no ground truth: each camera in turn is held out and predicted from k others)
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path

log = logging.getLogger(__name__)

DATASETS = ("synthetic", "shelf", "campus", "panoptic", "h36m", "recording")


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", required=True, choices=DATASETS)
    parser.add_argument(
        "--root",
        default=None,
        help="dataset folder (synthetic: a pose bank .npz, a motion folder, or an MHP "
        "directory from rmpl generate; not used by recording)",
    )
    parser.add_argument(
        "--calib",
        default=None,
        help="recording: the calibration file or folder (any format rmpl reads)",
    )
    parser.add_argument(
        "--skeleton", default=None, help="recording: 2D joint set when ambiguous (body25, body25b)"
    )
    parser.add_argument("--fps", type=float, default=None, help="recording: frame rate if none")
    parser.add_argument(
        "--min-score",
        type=float,
        default=0.5,
        help="recording: a held-out detection is a reference when its confidence is >= this",
    )
    parser.add_argument(
        "--methods",
        default="triangulate,robust,rmpl",
        help="comma-separated: triangulate, robust, rmpl[:MODEL]",
    )
    parser.add_argument(
        "--views",
        default=None,
        help="'all', 'pairs' and/or view counts k (mean over every k-subset of the cameras), "
        "e.g. 1,2,3,4,5 (default: all,pairs; synthetic: 1,2,3,4,5)",
    )
    parser.add_argument(
        "--poses",
        nargs="+",
        default=None,
        metavar="[NAME=]FILE",
        help="score finished 3D results (rmpl run's poses.npz/.json, a TRC) instead of "
        "running --methods; NAME defaults to the file's folder name",
    )
    parser.add_argument("--out", default=None, help="folder for the tables and plots")
    parser.add_argument(
        "--keypoints",
        nargs="+",
        default=None,
        help="2D input from files (any format rmpl reads; one per camera or one file), "
        "matched to the ground truth by frame number",
    )
    parser.add_argument(
        "--2d",
        dest="two_d",
        default="auto",
        choices=("auto", "detections", "annotations", "projection"),
        help="2D source when --keypoints is not given: the dataset's detections, its 2D "
        "annotations (Shelf/Campus actorsGT, H36M 'part'), or the ground truth projected "
        "through the noise model (auto: detections if any, else projection)",
    )
    parser.add_argument("--subject", default=None, help="h36m: one subject (default: all)")
    parser.add_argument("--sequence", default=None, help="panoptic: one sequence (default: all)")
    parser.add_argument(
        "--cameras",
        default=None,
        help="panoptic: comma-separated HD cameras (default 00_03,00_06,00_12,00_13,00_23); "
        "synthetic: 'random' (default) or 'sphere' (two cameras, see --heights/--angles)",
    )
    parser.add_argument(
        "--frames",
        default="eval",
        choices=("eval", "all"),
        help="shelf/campus VoxelPose layout: the customary evaluation frames or all",
    )
    parser.add_argument(
        "--dropout", default="0", help="keypoint removal probabilities, e.g. 0,0.1,0.2,0.3"
    )
    parser.add_argument(
        "--calib-noise",
        default=None,
        metavar="DEG,MM",
        help="Gaussian extrinsic noise at test time: rotation std in degrees, camera-centre "
        "std in millimetres (thesis: 2,20)",
    )
    parser.add_argument(
        "--calib-reps", type=int, default=5, help="calibration-noise draws averaged"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of every random draw")
    parser.add_argument("--pck", type=float, default=150.0, help="PCK threshold, millimetres")
    parser.add_argument(
        "--holdout", default="03", help="synthetic: held-out subjects, comma-separated"
    )
    parser.add_argument(
        "--samples", type=int, default=2000, help="synthetic: scenes per view count / point"
    )
    parser.add_argument(
        "--heights", default="2.2,3.2,4", help="synthetic sphere: camera heights, metres"
    )
    parser.add_argument(
        "--angles",
        default=",".join(str(a) for a in range(10, 181, 10)),
        help="synthetic sphere: horizontal angles between the two cameras, degrees",
    )
    parser.add_argument(
        "--radius", type=float, default=6.0, help="synthetic sphere: radius, metres"
    )
    parser.add_argument("--no-plots", action="store_true", help="tables only")
    parser.set_defaults(run=run)


def _floats(text: str, option: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(None, option, "comma-separated numbers", text) from None
    if not values or not all(np.isfinite(values)):
        raise InputError(None, option, "comma-separated finite numbers", text)
    return values


def _calib(args) -> tuple[float, float] | None:
    if args.calib_noise is None:
        return None
    values = _floats(args.calib_noise, "--calib-noise")
    if len(values) != 2:
        raise InputError(None, "--calib-noise", "DEG,MM (two numbers)", args.calib_noise)
    return values[0], values[1] / 1000.0


def _methods(spec: str) -> dict:
    from rmpl.evaluate.harness import make_method

    names = [m.strip() for m in spec.split(",") if m.strip()]
    if not names:
        raise InputError(None, "--methods", "at least one method", spec)
    if len(set(names)) != len(names):
        raise InputError(None, "--methods", "each method once", spec)
    return {name: make_method(name) for name in names}


def run(args: argparse.Namespace) -> int:
    from rmpl.evaluate.harness import EvalConfig

    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise InputError(args.out, None, "an output folder", "an existing file")
    config = EvalConfig(
        dropout=tuple(_floats(args.dropout, "--dropout")),
        calib_noise=_calib(args),
        calib_reps=args.calib_reps,
        seed=args.seed,
        pck_threshold=args.pck / 1000.0,
    )
    methods = _methods(args.methods)
    if args.dataset == "recording":
        return _run_recording(args, methods)
    if args.root is None:
        raise InputError(None, "--root", f"the {args.dataset} dataset folder", "none")
    if args.calib is not None:
        raise InputError(None, "--calib", "only with --dataset recording", args.calib)
    if args.dataset == "synthetic":
        if args.poses:
            raise InputError(None, "--poses", "a real dataset (finished results)", "synthetic")
        return _run_synthetic(args, config, methods)
    if args.cameras == "sphere" or args.cameras == "random":
        raise InputError(None, "--cameras", f"camera names for {args.dataset}", args.cameras)
    from rmpl.evaluate.harness import evaluate, evaluate_poses, load_eval_set, view_subsets

    if args.poses:
        _check_poses_options(args)

    evset = load_eval_set(
        args.dataset,
        args.root,
        two_d=args.two_d,
        keypoints=args.keypoints,
        subject=args.subject,
        sequence=args.sequence,
        cameras=args.cameras.split(",") if args.cameras else None,
        frames=args.frames,
        seed=args.seed,
    )
    if args.poses:
        ev = evaluate_poses(evset, _results(args), config)
    else:
        view_sets = view_subsets(evset.num_views, args.views or "all,pairs")
        ev = evaluate(evset, methods, view_sets, config)
    files = _real_outputs(ev, args)
    print(files["results.md"])
    if args.out:
        _write(Path(args.out), files, ev if not args.no_plots else None)
    return 0


# --------------------------------------------------------------------------- recordings


def _run_recording(args, methods: dict) -> int:
    """Held-out-view reprojection errors on a recording without 3D ground truth."""
    from rmpl.cli._common import load_calibration_and_2d
    from rmpl.evaluate.harness import markdown_table
    from rmpl.evaluate.heldout import heldout_rows, heldout_view_errors
    from rmpl.pipeline.runner import associate_frames

    if args.calib is None or not args.keypoints:
        raise InputError(None, "--calib/--keypoints", "both, for --dataset recording", "missing")
    for option, value in (
        ("--root", args.root),
        ("--poses", args.poses),
        ("--dropout", None if _floats(args.dropout, "--dropout") == [0.0] else args.dropout),
        ("--calib-noise", args.calib_noise),
        ("--cameras", args.cameras),
        ("--subject", args.subject),
        ("--sequence", args.sequence),
    ):
        if value is not None:
            raise InputError(None, option, f"no {option} with --dataset recording", value)
    if not (np.isfinite(args.min_score) and 0 < args.min_score <= 1):
        raise InputError(None, "--min-score", "a confidence in (0, 1]", args.min_score)
    inputs = load_calibration_and_2d(args)
    V = len(inputs.rig)
    if V < 2:
        raise InputError(args.calib, "cameras", "at least 2 (one is held out)", V)
    spec = args.views or ",".join(str(k) for k in range(1, V))
    try:
        sizes = sorted({int(x) for x in spec.split(",") if x.strip()})
    except ValueError:
        raise InputError(None, "--views", f"view counts in 1..{V - 1}", spec) from None
    if not sizes or not all(1 <= k <= V - 1 for k in sizes):
        raise InputError(None, "--views", f"view counts in 1..{V - 1}", spec)
    people = associate_frames(inputs.keypoints, inputs.scores, inputs.rig, progress=True)
    people = [a for a in people if len(a)]
    if not people:
        raise InputError(", ".join(args.keypoints), "people", "a person seen in 2+ views", "none")
    kp = np.concatenate([a.keypoints for a in people])
    sc = np.concatenate([a.scores for a in people])
    ev = heldout_view_errors(
        kp, sc, inputs.rig, methods, sizes, min_score=args.min_score, progress=True
    )
    rows = heldout_rows(ev)
    cols = [
        "views",
        "method",
        "subsets",
        "references",
        "coverage",
        "px_all",
        "px_common",
        "px_median_common",
        "mm_common",
        "mm_median_common",
    ]
    text = [
        "# rmpl evaluate: recording (held-out views, no ground truth)",
        "",
        f"`{_command(args)}`",
        "",
        f"{len(kp)} person-frames from {len(inputs.keypoints)} frames, cameras "
        f"{', '.join(inputs.rig.names)}. Each camera in turn is held out; each method "
        "estimates from k of the others, and its estimate is projected into the held-out "
        f"camera and compared with that camera's detections of confidence >= {args.min_score:g}."
        " px: pixels in the held-out image; mm: the same error across the held-out camera's "
        "ray at the joint's depth. _common: on the detections every method estimated. People "
        "are associated across all cameras, the held-out one included (to know which of its "
        "detections to compare), so the association step has seen it.",
        "",
        markdown_table(rows, cols),
    ]
    print("\n".join(text))
    if args.out:
        _write(Path(args.out), {"results.md": "\n".join(text), "results.csv": rows}, None)
    return 0


# --------------------------------------------------------------------------- real datasets


def _check_poses_options(args) -> None:
    """--poses scores fixed results: the options that change the 2D input cannot apply."""
    for option, value in (
        ("--views", args.views),
        ("--dropout", None if args.dropout == "0" else args.dropout),
        ("--calib-noise", args.calib_noise),
        ("--keypoints", args.keypoints),
    ):
        if value is not None:
            raise InputError(None, option, f"no {option} with --poses (fixed results)", value)


def _results(args) -> dict:
    """--poses [NAME=]FILE ... -> name -> Poses3D."""
    from rmpl.io.poses import load_poses

    out = {}
    for item in args.poses:
        name, sep, path = item.partition("=")
        if not sep:
            path = item
            name = Path(item).parent.name or Path(item).stem
        if name in out:
            raise InputError(item, "--poses", "a distinct name per result (NAME=FILE)", name)
        out[name] = load_poses(path)
    return out


def _command(args) -> str:
    """The command line that reproduces this run (every option not at its default)."""
    import shlex

    parser = argparse.ArgumentParser()
    register(parser)
    words = ["rmpl", "evaluate"]
    for action in parser._actions:
        if not action.option_strings or action.dest in ("help", "run"):
            continue
        value = getattr(args, action.dest, None)
        if value is None or value == action.default or value is False:
            continue
        words.append(action.option_strings[0])
        if value is not True:
            words += [str(v) for v in value] if isinstance(value, list) else [str(value)]
    return " ".join(shlex.quote(w) for w in words)


def _real_outputs(ev, args) -> dict[str, object]:
    """File name -> text (tables) for a real-dataset evaluation."""
    from rmpl.evaluate.harness import (
        header_lines,
        markdown_table,
        per_group_rows,
        per_joint_rows,
        results_rows,
    )

    cfg = ev.config
    pck_mm = 1000 * cfg.pck_threshold
    rows = results_rows(ev)
    sweep = len(cfg.dropout) > 1 or cfg.calib_noise is not None
    cols = ["views", "method", "mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage", "mpjpe_common"]
    if ev.evset.pcp:
        cols += [k for k in rows[0] if k.startswith("pcp_actor")] + ["pcp_mean"]
    if len(cfg.dropout) > 1:
        cols.insert(2, "dropout")
    if cfg.calib_noise is not None:
        cols.insert(2, "calib_noise")
    text = [f"# rmpl evaluate: {ev.evset.name}", "", f"`{_command(args)}`", ""]
    text += header_lines(ev) + [""]
    text.append(markdown_table(rows, cols, pck_mm))
    if sweep:
        text += ["", "Sweep (MPJPE, mm):", ""]
        text.append(_sweep_table(rows, cfg))
    by = "clip" if ev.evset.name == "h36m" else "person"
    groups = per_group_rows(ev, by)
    clean = [r for r in groups if r["dropout"] == cfg.dropout[0] and r["calib_noise"] == "none"]
    gcols = ["views", "method", by, "poses", "mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage"]
    if ev.evset.pcp and by == "person":
        gcols.append("pcp")
    text += [
        "",
        f"Per {'action/clip' if by == 'clip' else 'person'}"
        f" (dropout {cfg.dropout[0]:g}, no calibration noise):",
        "",
    ]
    text.append(markdown_table(clean, gcols, pck_mm))
    return {
        "results.md": "\n".join(text),
        "results.csv": rows,
        "per_joint.csv": per_joint_rows(ev),
        f"per_{'clip' if by == 'clip' else 'person'}.csv": groups,
    }


def _sweep_table(rows: list[dict], cfg) -> str:
    """MPJPE with one column per condition (dropout p / calibration noise)."""
    conds = []
    for r in rows:
        c = (r["dropout"], r["calib_noise"])
        if c not in conds:
            conds.append(c)
    title = [
        (f"p={d:g}" if len(cfg.dropout) > 1 else "")
        + (" " if len(cfg.dropout) > 1 and cfg.calib_noise else "")
        + (("calib " + c) if cfg.calib_noise is not None else "")
        for d, c in conds
    ]
    lines = ["| views | method | " + " | ".join(title) + " |"]
    lines.append("|---|---|" + "---:|" * len(conds))
    seen = []
    for r in rows:
        key = (r["views"], r["method"])
        if key in seen:
            continue
        seen.append(key)
        vals = {
            (x["dropout"], x["calib_noise"]): x["mpjpe"]
            for x in rows
            if (x["views"], x["method"]) == key
        }
        cells = [f"{vals[c]:.1f}" if np.isfinite(vals.get(c, np.nan)) else "—" for c in conds]
        lines.append(f"| {key[0]} | {key[1]} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _write(out: Path, files: dict[str, object], ev) -> None:
    from rmpl.evaluate.harness import write_csv

    out.mkdir(parents=True, exist_ok=True)
    for name, content in files.items():
        if isinstance(content, str):
            with atomic_path(out / name) as tmp:
                tmp.write_text(content)
        elif isinstance(content, dict):
            with atomic_path(out / name) as tmp:
                tmp.write_text(json.dumps(content, indent=1, default=float))
        else:
            write_csv(out / name, content)
    if ev is not None:
        _real_plots(out, ev)
    log.info("wrote %s into %s", ", ".join(files), out)


def _real_plots(out: Path, ev) -> None:
    from rmpl.evaluate.harness import joint_errors_mm, results_rows
    from rmpl.evaluate.plots import joint_bars, joint_boxplot, sweep_plot

    cfg = ev.config
    errors, bars = {}, {}
    for label in ev.view_sets:
        errors[label] = {m: joint_errors_mm(ev, label, 0, m) for m in ev.methods}
        bars[label] = {
            m: {j: float(e.mean()) if e.size else np.nan for j, e in errors[label][m].items()}
            for m in ev.methods
        }
    title = f"{ev.evset.name}, per-joint error"
    joint_boxplot(errors, out / "joint_errors_box.png", title)
    joint_bars(bars, out / "joint_mpjpe_bar.png", title.replace("error", "MPJPE"))
    rows = results_rows(ev)
    if len(cfg.dropout) > 1:
        curves = {}
        for label in ev.view_sets:
            for m in ev.methods:
                sel = [
                    r
                    for r in rows
                    if r["views"] == label and r["method"] == m and r["calib_noise"] == "none"
                ]
                curves[f"{m} | {label}"] = ([r["dropout"] for r in sel], [r["mpjpe"] for r in sel])
        sweep_plot(
            curves,
            out / "dropout.png",
            "keypoint dropout probability p",
            title=f"{ev.evset.name}: MPJPE vs keypoint dropout",
        )
    if cfg.calib_noise is not None:
        curves = {}
        for label in ev.view_sets:
            for m in ev.methods:
                sel = [
                    r
                    for r in rows
                    if r["views"] == label and r["method"] == m and r["dropout"] == cfg.dropout[0]
                ]
                curves[f"{m} | {label}"] = ([0, 1], [r["mpjpe"] for r in sel])
        deg, mm = cfg.calib_noise[0], 1000 * cfg.calib_noise[1]
        sweep_plot(
            curves,
            out / "calib_noise.png",
            f"calibration noise (0 = none, 1 = {deg:g} deg / {mm:g} mm)",
            title=f"{ev.evset.name}: MPJPE with calibration noise",
        )
    counts = [label for label in ev.view_sets if label.split()[0].isdigit()]
    if len(counts) > 1:
        curves = {}
        for m in ev.methods:
            sel = [
                r
                for r in rows
                if r["method"] == m
                and r["views"] in counts
                and r["dropout"] == cfg.dropout[0]
                and r["calib_noise"] == "none"
            ]
            curves[m] = ([int(r["views"].split()[0]) for r in sel], [r["mpjpe"] for r in sel])
        sweep_plot(
            curves,
            out / "views.png",
            "number of views",
            title=f"{ev.evset.name}: MPJPE vs number of views",
        )


# --------------------------------------------------------------------------- synthetic


def _run_synthetic(args, config, methods) -> int:
    from rmpl.cli.train import load_poses

    mode = args.cameras or "random"
    if mode not in ("random", "sphere"):
        raise InputError(None, "--cameras", "'random' or 'sphere' for synthetic", mode)
    if args.keypoints:
        raise InputError(None, "--keypoints", "no 2D files for synthetic (2D is simulated)")
    if args.samples < 1:
        raise InputError(None, "--samples", "a positive number", args.samples)
    shards = _mhp_root(args.root)
    if shards is not None:
        if mode == "sphere":
            raise InputError(
                args.root,
                "--cameras sphere",
                "a pose bank (MHP renders have their own cameras)",
                "an MHP directory",
            )
        meta = json.loads((shards / "manifest.json").read_text())
        counts = meta.get("counts", {})
        held = None
        head = [
            "# rmpl evaluate: synthetic (MHP renders)",
            "",
            f"`{_command(args)}`",
            "",
            f"- scenes: MHP directory {args.root} ({counts.get('meshes', '?')} meshes x "
            f"{counts.get('views', '?')} views; its subjects: "
            f"{', '.join(meta.get('pose_bank', {}).get('subjects', {})) or '?'}); each "
            "scene is one mesh seen by V of its views drawn at random",
            f"- 2D: the real detector's output on the renders ({meta.get('detector', '?')}), "
            f"seed {config.seed}; every method gets the same 2D",
            "- scored joints: all 17 COCO joints regressed from the mesh; KP*: the 12 limb "
            f"joints; PCK threshold {args.pck:g} mm (a missing joint is wrong)",
        ]
    else:
        bank = load_poses(args.root)
        _, held = bank.split(args.holdout.split(","))
        if not len(held):
            raise ValueError(f"{args.root}: no poses of held-out subjects {args.holdout}")
        head = [
            f"# rmpl evaluate: synthetic ({mode} cameras)",
            "",
            f"`{_command(args)}`",
            "",
            f"- poses: {len(held)} held-out poses of subjects {args.holdout} from {args.root}",
            "- 2D: the parametric detector noise model (rmpl.synth.noise defaults), seed "
            f"{config.seed}; every method gets the same 2D",
            "- scored joints: all 17 COCO joints; KP*: the 12 limb joints; PCK threshold "
            f"{args.pck:g} mm (a missing joint is wrong)",
        ]
    if mode == "sphere":
        return _run_sphere(args, config, held.poses, methods, head)
    from rmpl.evaluate.harness import markdown_table, pose_metrics, write_csv
    from rmpl.evaluate.synthetic import evaluate_synthetic

    counts = _view_counts(args.views)
    preds: dict = {}
    rows = evaluate_synthetic(
        None if held is None else held.poses,
        methods,
        counts,
        args.samples,
        seed=config.seed,
        dropout=config.dropout,
        calib_noise=config.calib_noise,
        calib_reps=config.calib_reps if config.calib_noise else 1,
        pck_threshold=config.pck_threshold,
        predictions=preds,
        shards=shards,
    )
    if shards is None:
        head.append(
            f"- scenes: {args.samples} per view count and condition, random camera setups "
            "(preset 'universal'), the person anywhere in a 4 x 4 m room"
        )
    else:
        head.append(f"- {args.samples} scenes per view count and condition")
    if config.calib_noise:
        head.append(
            f"- calibration noise {config.calib_noise[0]:g} deg / "
            f"{1000 * config.calib_noise[1]:g} mm on the methods' extrinsics, "
            f"{config.calib_reps} draws"
        )
    cols = ["views", "method", "mpjpe", "kpstar", "pa_mpjpe", "pck", "coverage", "mpjpe_common"]
    if len(config.dropout) > 1:
        cols.append("dropout")
    if config.calib_noise:
        cols.append("calib_noise")
    text = "\n".join(head) + "\n\n" + markdown_table(rows, cols, args.pck)
    joint_rows = []
    errors: dict = {}
    for (v, p, calib, m), (pred, target) in preds.items():
        for j in range(17):
            r = pose_metrics(pred, target, [j], config.pck_threshold)
            joint_rows.append(
                {
                    "views": v,
                    "method": m,
                    "joint": _joint(j),
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
                _joint(j): e[:, j][np.isfinite(e[:, j])] for j in range(17)
            }
    print(text)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        with atomic_path(out / "results.md") as tmp:
            tmp.write_text(text)
        write_csv(out / "results.csv", rows)
        write_csv(out / "per_joint.csv", joint_rows)
        if not args.no_plots:
            _synthetic_plots(out, rows, errors, config)
    return 0


def _mhp_root(root: str) -> Path | None:
    """``root`` when it is an MHP directory (a manifest.json beside shards), else None."""
    p = Path(root)
    return p if (p / "manifest.json").is_file() else None


def _joint(j: int) -> str:
    from rmpl.skeleton import COCO17

    return COCO17.joints[j]


def _view_counts(spec: str | None) -> list[int]:
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


def _synthetic_plots(out: Path, rows, errors, config) -> None:
    from rmpl.evaluate.plots import joint_bars, joint_boxplot, sweep_plot

    joint_boxplot(errors, out / "joint_errors_box.png", "synthetic, per-joint error")
    bars = {
        label: {
            m: {j: float(e.mean()) if e.size else np.nan for j, e in d.items()}
            for m, d in per.items()
        }
        for label, per in errors.items()
    }
    joint_bars(bars, out / "joint_mpjpe_bar.png", "synthetic, per-joint MPJPE")
    methods = list(dict.fromkeys(r["method"] for r in rows))
    counts = list(dict.fromkeys(r["views"] for r in rows))
    if len(config.dropout) > 1:
        curves = {}
        for m in methods:
            for v in counts:
                sel = [
                    r
                    for r in rows
                    if r["method"] == m and r["views"] == v and r["calib_noise"] == "none"
                ]
                curves[f"{m} | {v} views"] = (
                    [r["dropout"] for r in sel],
                    [r["mpjpe"] for r in sel],
                )
        sweep_plot(
            curves,
            out / "dropout.png",
            "keypoint dropout probability p",
            title="synthetic: MPJPE vs keypoint dropout",
        )
    if len(counts) > 1:
        curves = {}
        for m in methods:
            sel = [
                r
                for r in rows
                if r["method"] == m
                and r["dropout"] == config.dropout[0]
                and r["calib_noise"] == "none"
            ]
            curves[m] = ([r["views"] for r in sel], [r["mpjpe"] for r in sel])
        sweep_plot(
            curves,
            out / "views.png",
            "number of views",
            title="synthetic: MPJPE vs number of views",
        )


def _run_sphere(args, config, poses, methods, head) -> int:
    from rmpl.evaluate.harness import markdown_table, write_csv
    from rmpl.evaluate.synthetic import evaluate_sphere

    if args.views is not None:
        raise InputError(None, "--views", "no --views with --cameras sphere (always 2)", args.views)
    if len(config.dropout) > 1 or config.dropout[0] > 0 or config.calib_noise:
        raise InputError(None, "--cameras sphere", "no --dropout / --calib-noise in the sweep")
    heights = _floats(args.heights, "--heights")
    angles = _floats(args.angles, "--angles")
    if any(not 0 < a <= 180 for a in angles):
        raise InputError(None, "--angles", "angles in (0, 180] degrees", args.angles)
    rows = evaluate_sphere(
        poses,
        methods,
        heights,
        angles,
        args.samples,
        seed=config.seed,
        radius=args.radius,
        pck_threshold=config.pck_threshold,
    )
    head.append(
        f"- cameras: two, {args.radius:g} m from (0, 0, 1 m) (the person's mid-hip is above the "
        "origin) at the given height, azimuths -angle/2 and +angle/2, aimed at (0, 0, 1 m); "
        f"f = 1145 px, 1000 x 1000 px; {args.samples} scenes per point, the same at every point"
    )
    text = "\n".join(head) + "\n\n"
    text += markdown_table(
        rows,
        [
            "height",
            "angle",
            "method",
            "mpjpe",
            "kpstar",
            "pa_mpjpe",
            "pck",
            "coverage",
            "mpjpe_common",
        ],
        args.pck,
    )
    # Compact view: MPJPE, one column per method and height.
    methods_ = list(methods)
    cols = [(h, m) for h in heights for m in methods_]
    lines = [
        "| angle (deg) | " + " | ".join(f"{m} @ {h:g} m" for h, m in cols) + " |",
        "|---:|" + "---:|" * len(cols),
    ]
    for a in angles:
        cells = []
        for h, m in cols:
            r = next(x for x in rows if x["height"] == h and x["angle"] == a and x["method"] == m)
            cells.append(f"{r['mpjpe']:.1f}" if np.isfinite(r["mpjpe"]) else "—")
        lines.append(f"| {a:g} | " + " | ".join(cells) + " |")
    text += "\nMPJPE (mm) by angle:\n\n" + "\n".join(lines) + "\n"
    lines = lines[:2]
    for a in angles:
        cells = []
        for h, m in cols:
            r = next(x for x in rows if x["height"] == h and x["angle"] == a and x["method"] == m)
            cells.append(f"{r['mpjpe_common']:.1f}" if np.isfinite(r["mpjpe_common"]) else "—")
        lines.append(f"| {a:g} | " + " | ".join(cells) + " |")
    text += (
        "\nMPJPE (mm) by angle on the joints every method estimated (triangulation needs a "
        "joint in both views):\n\n" + "\n".join(lines) + "\n"
    )
    print(text)
    if args.out:
        from rmpl.evaluate.plots import sweep_plot

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        with atomic_path(out / "results.md") as tmp:
            tmp.write_text(text)
        write_csv(out / "results.csv", rows)
        if not args.no_plots:
            curves = {
                f"{m} | {h:g} m": (
                    angles,
                    [
                        next(
                            x["mpjpe"]
                            for x in rows
                            if x["height"] == h and x["angle"] == a and x["method"] == m
                        )
                        for a in angles
                    ],
                )
                for h in heights
                for m in methods_
            }
            sweep_plot(
                curves,
                out / "sphere.png",
                "horizontal angle between the cameras (deg)",
                title=f"two cameras on a {args.radius:g} m sphere: MPJPE vs angle",
            )
            common = {
                key: (
                    angles,
                    [
                        next(
                            x["mpjpe_common"]
                            for x in rows
                            if x["height"] == float(key.split(" | ")[1][:-2])
                            and x["angle"] == a
                            and x["method"] == key.split(" | ")[0]
                        )
                        for a in angles
                    ],
                )
                for key in curves
            }
            sweep_plot(
                common,
                out / "sphere_common_joints.png",
                "horizontal angle between the cameras (deg)",
                title="MPJPE vs angle on the joints every method estimated",
            )
    return 0
