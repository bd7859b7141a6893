"""The ``rmpl run`` options that the chosen path does not use: said, never dropped in silence.

``rmpl run --cutoff 50`` with the temporal model gives the same poses as ``--filter none``
(the temporal model lifts whole tracks and does not filter them); ``--detector`` does
nothing with 2D files; ``--fps`` nothing when the input states its frame rate.
:func:`unused_options` lists each such option given (set away from its default) as one
sentence; :func:`warn_unused_options` logs them at WARNING. The floor has its own messages
(:func:`rmpl.cli._common.warn_unused_floor`, :func:`rmpl.pipeline.runner.run`).
"""

from __future__ import annotations

import argparse
import functools
import logging

__all__ = ["unused_options", "warn_unused_options"]

log = logging.getLogger(__name__)


@functools.cache
def _defaults() -> dict:
    """``rmpl run``'s defaults, from its own parser."""
    from rmpl.cli.run import register

    parser = argparse.ArgumentParser(add_help=False)
    register(parser)
    return {a.dest: a.default for a in parser._actions}


def _given(args: argparse.Namespace, dest: str) -> bool:
    return getattr(args, dest, None) != _defaults().get(dest)


def _filter_lines(args: argparse.Namespace, temporal: bool) -> list[str]:
    changed = [f"--{d}" for d in ("filter", "cutoff") if _given(args, d)]
    if not changed:
        return []
    if temporal:
        return [
            f"{' and '.join(changed)} not used: the temporal model ({args.model}) lifts whole "
            "tracks and does not filter them (the poses are those of --filter none); give a "
            "per-frame model (--model floor26) to filter its answers your way"
        ]
    if _given(args, "cutoff") and args.filter != "butterworth":
        return [f"--cutoff not used: --filter {args.filter} has no Butterworth cut-off"]
    return []


def unused_options(
    args: argparse.Namespace, input_fps: float | None = None, auto_model: bool = False
) -> list[str]:
    """The options of a parsed ``rmpl run`` that its path does not use, one sentence each.

    Args:
        args: the parsed options, ``args.model`` already resolved (the model used).
        input_fps: the frame rate the run uses (the input's own, else ``--fps``).
        auto_model: ``--model`` was not given (``args.model`` is rmpl run's choice).
    """
    temporal = False
    if args.method == "rmpl" and args.model is not None:
        from rmpl.models import is_temporal_checkpoint

        temporal = is_temporal_checkpoint(args.model)
    lines = _filter_lines(args, temporal)
    if args.method != "rmpl" and not auto_model and _given(args, "model"):
        lines.append(f"--model not used: --method {args.method} triangulates, it does not lift")
    if getattr(args, "keypoints", None):
        if _given(args, "detector"):
            lines.append("--detector not used: the 2D comes from --keypoints files")
        if _given(args, "no_overlay"):
            lines.append("--no-overlay not used: overlays are drawn for videos and images only")
    elif _given(args, "skeleton"):
        lines.append("--skeleton not used: the detector's joint set is known (it is for files)")
    if _given(args, "fps") and input_fps is not None and input_fps != args.fps:
        lines.append(
            f"--fps {args.fps:g} not used: the input states its frame rate, {input_fps:g} frames/s"
        )
    return lines


def warn_unused_options(
    args: argparse.Namespace, input_fps: float | None = None, auto_model: bool = False
) -> list[str]:
    """:func:`unused_options`, each logged at WARNING; returns them."""
    lines = unused_options(args, input_fps, auto_model)
    for line in lines:
        log.warning("WARNING: %s", line)
    return lines
