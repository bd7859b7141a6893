"""Generate MHP training data: anny bodies posed from mocap, rendered, run through a detector.

Examples:
  rmpl generate configs/mhp.toml --out /data/mhp --set poses="PATH/TO/cmu_mocap" --workers 2
  rmpl generate configs/mhp.toml --out /data/mhp --ray auto      (shards as Ray tasks)
  rmpl generate configs/mhp_seq.toml --out /data/mhp_seq --set poses="PATH/TO/cmu_mocap"
                                          (sequences: one body, motion and rig per sequence)
  rmpl generate configs/mhp.toml --out /data/scenes --set 'people=[2, 4]' \
      --set 'detector="blazepose-multi-static"'  (multi-person scenes, mutual occlusion)
  rmpl generate --stats /data/mhp [--noise-out noise.toml]       (detector error report)

Re-running the same command resumes: finished shards are skipped.
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("config", nargs="?", help="generator config TOML (see configs/mhp.toml)")
    parser.add_argument("--out", help="output directory (resumes if it holds the same run)")
    parser.add_argument("--workers", type=int, default=1, help="local worker processes")
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run shards on a Ray cluster ('auto', host:port, or 'local' for a local instance)",
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a config value (TOML syntax), e.g. --set num_meshes=200",
    )
    parser.add_argument(
        "--stats",
        metavar="DIR",
        help="report detector error, miss rate and calibration of the shards in DIR and fit "
        "the parametric noise model to them",
    )
    parser.add_argument(
        "--noise-out",
        metavar="FILE",
        help="with --stats: where to write the fitted noise table (default DIR/noise.toml)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.stats:
        from rmpl.synth.noise_fit import detector_stats, write_noise

        _refuse_sequences(args.stats)
        report = detector_stats(args.stats)
        print(report.markdown())
        path = write_noise(report, args.noise_out or f"{args.stats}/noise.toml")
        print(f"\nfitted noise parameters: {path} (use it as the [noise] table of a train config)")
        return 0
    if not args.config or not args.out:
        raise ValueError("rmpl generate needs CONFIG.toml and --out DIR (or --stats DIR)")
    from rmpl.synth.generate import GenerateConfig, generate

    cfg = GenerateConfig.from_toml(args.config, args.overrides)
    if args.workers < 1:
        raise ValueError(f"--workers must be >= 1, got {args.workers}")
    generate(
        cfg, args.out, workers=args.workers, ray_address=args.ray, progress=not args.no_progress
    )
    return 0


def _refuse_sequences(root: str) -> None:
    """--stats fits the per-image noise model: it reads single-frame sets only."""
    import json
    from pathlib import Path

    from rmpl.errors import InputError
    from rmpl.synth.generate import SEQUENCE_FORMAT

    manifest = Path(root) / "manifest.json"
    if manifest.is_file():
        fmt = json.loads(manifest.read_text()).get("format")
        if fmt == SEQUENCE_FORMAT:
            raise InputError(manifest, "format", "a single-frame MHP set for --stats", fmt)
