"""``rmpl evaluate``'s options resolved into one evaluation: which protocol runs, with which
methods and conditions, and which options cannot apply to it (refused, naming the option).

:func:`evaluate_command` takes the parsed options and the command line to quote, and returns
the :class:`rmpl.evaluate.tables.Report` that the command prints and saves.
"""

from __future__ import annotations

from rmpl.errors import InputError

__all__ = ["evaluate_command"]


def evaluate_command(args, command: str):
    """The evaluation ``args`` (the parsed options of ``rmpl evaluate``) ask for."""
    from rmpl.evaluate.options import eval_config
    from rmpl.evaluate.registry import parse_methods
    from rmpl.evaluate.sequences import dataset_fps

    fps = dataset_fps(args.dataset, args.fps)
    config = eval_config(
        args.dropout, args.calib_noise, args.calib_reps, args.seed, args.pck, fps=fps
    )
    _refuse_sequences(args)  # before any model is loaded
    methods = parse_methods(args.methods)
    floor = getattr(args, "floor", None)
    _check_floor_option(floor, methods, args.dataset)
    if args.dataset == "recording":
        return _recording(args, methods, command, set_floor(methods, floor))
    if args.root is None:
        raise InputError(None, "--root", f"the {args.dataset} dataset folder", "none")
    if args.calib is not None:
        raise InputError(None, "--calib", "only with --dataset recording", args.calib)
    if args.dataset == "synthetic":
        set_floor(methods, floor)
        return _synthetic(args, config, methods, command)
    return _benchmark(args, config, methods, command)


def _recording(args, methods, command: str, floor_note: str = ""):
    """Held-out-view errors on a recording: calibration + 2D files, no ground truth;
    ``floor_note``: what :func:`set_floor` gave the ``rmpl+floor`` methods."""
    from rmpl.evaluate.options import check_min_score, parse_floats, refuse
    from rmpl.evaluate.protocols import run_recording
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    if args.calib is None or not args.keypoints:
        raise InputError(None, "--calib/--keypoints", "both, for --dataset recording", "missing")
    dropout = None if parse_floats(args.dropout, "--dropout") == [0.0] else args.dropout
    refuse(
        [
            ("--root", args.root),
            ("--poses", args.poses),
            ("--dropout", dropout),
            ("--calib-noise", args.calib_noise),
            ("--cameras", args.cameras),
            ("--subject", args.subject),
            ("--sequence", args.sequence),
        ],
        "with --dataset recording",
    )
    check_min_score(args.min_score)
    inputs = load_inputs(InputSpec.from_args(args))
    return run_recording(
        inputs.keypoints,
        inputs.scores,
        inputs.rig,
        methods,
        views=args.views,
        min_score=args.min_score,
        command=command,
        calib=args.calib,
        sources=args.keypoints,
        notes=(floor_note,) if floor_note else (),
    )


def _synthetic(args, config, methods, command: str):
    from rmpl.evaluate.experiments import SyntheticOptions, run_synthetic

    if args.poses:
        raise InputError(None, "--poses", "a real dataset (finished results)", "synthetic")
    opts = SyntheticOptions(
        args.root, args.cameras, args.views, args.samples, args.holdout, args.heights,
        args.angles, args.radius, args.pck, args.keypoints,
    )  # fmt: skip
    return run_synthetic(opts, methods, config, command)


def _benchmark(args, config, methods, command: str):
    """A dataset with 3D ground truth: run the methods, or score finished results."""
    from rmpl.evaluate.evalset import load_eval_set
    from rmpl.evaluate.options import refuse
    from rmpl.evaluate.protocols import load_results, run_benchmark, score_results

    if args.cameras == "sphere" or args.cameras == "random":
        raise InputError(None, "--cameras", f"camera names for {args.dataset}", args.cameras)
    if args.poses:
        given = [
            ("--views", args.views),
            ("--dropout", None if args.dropout == "0" else args.dropout),
            ("--calib-noise", args.calib_noise),
            ("--keypoints", args.keypoints),
        ]
        refuse(given, "with --poses (fixed results)")
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
        return score_results(evset, load_results(args.poses), config, command)
    note = set_floor(methods, getattr(args, "floor", None), evset)
    if note:
        from dataclasses import replace

        evset = replace(evset, notes=(*evset.notes, note))
    if any(getattr(m, "sequence", False) for m in methods.values()):
        from dataclasses import replace

        from rmpl.evaluate.sequences import sequence_note

        evset = replace(evset, notes=(*evset.notes, sequence_note(args.dataset, args.fps)))
    return run_benchmark(evset, methods, config, args.views, command)


def _refuse_sequences(args) -> None:
    """Sequence methods need frames in time: not the synthetic scenes, not --poses."""
    from rmpl.evaluate.sequences import needs_time

    seq = [n.strip() for n in args.methods.split(",") if needs_time(n.strip())]
    if seq and (args.dataset in ("synthetic", "recording") or args.poses):
        where = "--poses" if args.poses else f"--dataset {args.dataset}"
        raise InputError(None, "--methods", f"per-frame methods with {where}", ",".join(seq))


#: ``--floor`` words besides a plane (``AXIS=H`` or ``nx,ny,nz,d``).
FLOOR_WORDS = ("convention", "estimate", "none")


def _check_floor_option(floor: str | None, methods: dict, dataset: str) -> None:
    """``--floor`` needs an ``rmpl+floor`` method; "estimate" needs a multi-view dataset."""
    from rmpl.evaluate.methods import MonocularMethod

    if floor is None:
        return
    if not any(isinstance(m, MonocularMethod) for m in methods.values()):
        raise InputError(None, "--floor", "an rmpl+floor method in --methods", floor)
    if floor == "estimate" and dataset in ("synthetic", "recording"):
        raise InputError(
            None, "--floor", "a plane (AXIS=H or nx,ny,nz,d), 'convention' or 'none' for "
            f"--dataset {dataset} ('estimate' needs a dataset's multi-view frames)", floor,
        )  # fmt: skip


def set_floor(methods: dict, spec: str | None, evset=None) -> str:
    """Give the ``rmpl+floor`` methods their floor; returns the results.md header note.

    Args:
        spec: ``--floor``: None or "convention" (the rig's convention, if it has one),
            "none", "estimate" (from ``evset``'s own multi-view frames,
            :func:`rmpl.evaluate.harness.multi_view_floor`) or a plane
            (:func:`rmpl.geometry.floor.parse_floor`).
    """
    from rmpl.evaluate.methods import MonocularMethod
    from rmpl.geometry.floor import parse_floor

    mono = [m for m in methods.values() if isinstance(m, MonocularMethod)]
    if not mono:
        return ""
    floor, rule = None, "convention"
    if spec == "none":
        rule, text = "none", "no floor (size prior and time only)"
    elif spec == "estimate":
        from rmpl.evaluate.harness import multi_view_floor

        floor = multi_view_floor(evset)
        text = floor.describe()
    elif spec in (None, "convention"):
        text = (
            "the calibration convention (the cameras upright about a world axis, rolled "
            "less than 30 deg, the floor at 0 along it), when the rig has one"
        )
    else:
        floor = parse_floor(spec)
        text = floor.describe()
    for m in mono:
        m.floor, m.floor_rule = floor, rule
    return (
        "rmpl+floor (one view, also as rmpl+floor:CUES@MODEL: the lifter, `default` or "
        "MODEL, then depth from the cues: by default the floor, body size and time, or for a "
        "model that reads the floor, its own depth and time; with the time cue its people are "
        "tracked and filtered as rmpl run does; with 2+ views it is the plain lifter, given "
        "the floor if it reads "
        f"one): floor {text}"
    )
