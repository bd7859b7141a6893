"""Compare triangulation, robust triangulation and RMPL on a dataset with 3D ground truth.

Examples:
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --methods triangulate,robust,rmpl
  rmpl evaluate --dataset synthetic --root poses.npz --views 1,2,3,4,5 --out results/synth
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from rmpl.io.atomic import atomic_path

log = logging.getLogger(__name__)

DATASETS = ("shelf", "synthetic")


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dataset", required=True, choices=DATASETS)
    parser.add_argument("--root", required=True, help="dataset folder (or pose bank for synthetic)")
    parser.add_argument(
        "--methods",
        default="triangulate,robust,rmpl",
        help="comma-separated: triangulate, robust, rmpl[:MODEL]",
    )
    parser.add_argument(
        "--views", default="all,pairs", help="'all', 'pairs' and/or view counts, e.g. 1,2,3,4,5"
    )
    parser.add_argument("--out", default=None, help="folder for results.md / results.csv")
    parser.add_argument(
        "--holdout", default="03", help="synthetic: held-out subjects, comma-separated"
    )
    parser.add_argument(
        "--samples", type=int, default=2000, help="synthetic: scenes per view count"
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rmpl.evaluate import make_method, view_subsets

    names = [m.strip() for m in args.methods.split(",") if m.strip()]
    methods = {name: make_method(name) for name in names}
    if args.dataset == "shelf":
        from rmpl.data.shelf import load_shelf
        from rmpl.evaluate import evaluate_shelf, shelf_markdown

        data = load_shelf(args.root)
        ev = evaluate_shelf(data, methods, view_subsets(len(data.rig), args.views))
        text = shelf_markdown(ev)
        rows = [{"views": k[0], "method": k[1], **v} for k, v in ev.results.items()]
    else:
        from rmpl.cli.train import load_poses
        from rmpl.evaluate_synthetic import evaluate_synthetic, synthetic_markdown

        bank = load_poses(args.root)
        _, held = bank.split(args.holdout.split(","))
        if not len(held):
            raise ValueError(f"{args.root}: no poses of held-out subjects {args.holdout}")
        counts = [int(v) for v in args.views.split(",") if v.isdigit()] or [1, 2, 3, 4, 5]
        rows = evaluate_synthetic(held.poses, methods, counts, args.samples)
        text = synthetic_markdown(rows)
    print(text)
    if args.out:
        write_outputs(Path(args.out), text, rows)
    return 0


def write_outputs(out: Path, text: str, rows: list[dict]) -> None:
    import csv
    import io

    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "results.md") as tmp:
        tmp.write_text(text)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    with atomic_path(out / "results.csv") as tmp:
        tmp.write_text(buf.getvalue())
    log.info("wrote %s/results.md and results.csv", out)
