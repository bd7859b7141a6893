"""rmpl models prints one row per shipped model, with the rule's picks."""

from __future__ import annotations

from rmpl.cli import main
from rmpl.models import MODELS, ONE_CAMERA_NO_FLOOR, TEMPORAL


def test_rmpl_models_lists_every_shipped_model(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line.startswith("| `")]
    assert [r.split("`")[1] for r in rows] == [m.name for m in MODELS]
    picked = {r.split("`")[1]: r.rsplit("|", 2)[-2] for r in rows}
    assert "frame rate" in picked[TEMPORAL] and "without a floor" in picked[ONE_CAMERA_NO_FLOOR]
