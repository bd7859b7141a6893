"""The table of shipped models agrees with the weights, and rmpl run's one rule."""

from __future__ import annotations

import json
import logging

import pytest

from rmpl.models import (
    MODELS,
    ONE_CAMERA,
    ONE_CAMERA_NO_FLOOR,
    PER_FRAME,
    TEMPORAL,
    WEIGHTS,
    checkpoint_reads_floor,
    choose_model,
    is_temporal_checkpoint,
)


def test_every_shipped_folder_has_one_row_and_every_row_a_folder():
    folders = sorted(p.name for p in WEIGHTS.iterdir() if (p / "config.json").is_file())
    assert sorted(m.name for m in MODELS) == folders


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_a_row_says_what_its_checkpoint_is(model):
    meta = json.loads((model.path / "config.json").read_text())
    assert meta["skeleton"] == model.joints
    assert is_temporal_checkpoint(model.name) == model.time
    assert checkpoint_reads_floor(model.name) == model.floor
    assert model.size_mb() > 0.1


def test_the_defaults_are_shipped_models_of_the_right_kind():
    rows = {m.name: m for m in MODELS}
    assert not rows[PER_FRAME].time and rows[TEMPORAL].time
    assert rows[ONE_CAMERA].floor and not rows[ONE_CAMERA_NO_FLOOR].floor


def test_choose_model(caplog):
    assert choose_model(4, 30.0) == TEMPORAL
    assert choose_model(4, 30.0, whole_tracks=False) == PER_FRAME  # rmpl lift
    assert choose_model(4, 30.0, "triangulate") == PER_FRAME
    assert choose_model(1, 30.0) == ONE_CAMERA
    assert choose_model(1, 30.0, floor_known=False) == ONE_CAMERA_NO_FLOOR
    with caplog.at_level(logging.WARNING):
        assert choose_model(2, None) == PER_FRAME
    assert "no frame rate" in caplog.text


def test_a_checkpoint_folder_is_read_and_an_unknown_name_is_neither(tmp_path):
    (tmp_path / "config.json").write_text(
        json.dumps({"format": "rmpl-temporal-checkpoint-1", "model": {"floor": True}})
    )
    assert is_temporal_checkpoint(tmp_path) and checkpoint_reads_floor(str(tmp_path))
    assert not is_temporal_checkpoint("no-such-model")
    assert not checkpoint_reads_floor("no-such-model")
