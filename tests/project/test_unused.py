"""Options the chosen path does not use are said."""

from __future__ import annotations

import argparse

from rmpl.project.unused import unused_options


def _args(*argv: str, model: str | None = None) -> argparse.Namespace:
    from rmpl.cli.run import register

    parser = argparse.ArgumentParser()
    register(parser)
    args = parser.parse_args(["--calib", "c.toml", "--out", "o", *argv])
    args.model = args.model or model
    return args


def test_filter_options_with_the_temporal_model():
    (line,) = unused_options(_args("--keypoints", "k.json", "--cutoff", "50", model="temporal26"))
    assert "--cutoff" in line and "temporal" in line
    (line,) = unused_options(_args("--keypoints", "k.json", "--filter", "none", model="temporal26"))
    assert "--filter" in line
    assert unused_options(_args("--keypoints", "k.json", model="temporal26")) == []
    # a per-frame model filters: --cutoff is used
    assert unused_options(_args("--keypoints", "k.json", "--cutoff", "4", model="floor26")) == []


def test_cutoff_without_butterworth():
    args = _args("--keypoints", "k.json", "--filter", "one-euro", "--cutoff", "3", model="floor26")
    (line,) = unused_options(args)
    assert "--cutoff" in line and "one-euro" in line


def test_model_with_triangulation_and_detector_with_files():
    args = _args("--keypoints", "k.json", "--method", "robust", "--model", "floor26")
    assert any("--model" in line for line in unused_options(args))
    # rmpl run's own choice of model is not the user's: nothing to say
    assert unused_options(_args("--keypoints", "k.json", "--method", "robust", model="floor26"),
                          auto_model=True) == []  # fmt: skip
    lines = unused_options(
        _args("--keypoints", "k.json", "--detector", "mediapipe", "--no-overlay", model="floor26")
    )
    assert len(lines) == 2 and "--detector" in lines[0] and "--no-overlay" in lines[1]
    (line,) = unused_options(_args("--videos", "a.mp4", "--skeleton", "body25", model="floor26"))
    assert "--skeleton" in line


def test_fps_when_the_input_states_its_own():
    args = _args("--videos", "a.mp4", "--fps", "30", model="floor26")
    (line,) = unused_options(args, input_fps=60.0)
    assert "--fps 30" in line and "60" in line
    assert unused_options(args, input_fps=30.0) == []


def test_rmpl_run_says_it(tmp_path, caplog):
    """The hook in rmpl run: a fast triangulation run given a model it does not use."""
    import logging

    from rmpl.cli import main
    from tests.project.conftest import WALK

    argv = ["run", "--calib", str(WALK / "calibration.toml"), "--keypoints",
            str(WALK / "keypoints.json"), "--out", str(tmp_path / "out"), "--method",
            "triangulate", "--model", "floor26", "--no-pictures", "--formats", "npz",
            "--pose2sim", "off"]  # fmt: skip
    with caplog.at_level(logging.WARNING):
        assert main(argv) == 0
    assert any("--model not used" in r.getMessage() for r in caplog.records)
