"""The shipped models: one table, and the one rule by which ``rmpl run`` picks among them.

:data:`MODELS` lists every model shipped in ``rmpl/weights/``: its joint set, what it reads
besides the 2D (the floor plane, time), what it was selected on and its headline figures
(docs/results.md has the commands), and when ``rmpl run`` picks it. :func:`choose_model`
is that rule, the only place it is written; ``rmpl models`` prints the table.

This module reads no weights and imports no torch: the command line's parser uses it.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "MODELS",
    "PRETRAINED",
    "PRETRAINED_TEMPORAL",
    "ShippedModel",
    "checkpoint_reads_floor",
    "choose_model",
    "is_temporal_checkpoint",
]

log = logging.getLogger(__name__)

WEIGHTS = Path(__file__).parent / "weights"


@dataclass(frozen=True)
class ShippedModel:
    """One row of ``rmpl models``.

    Attributes:
        name: the ``--model`` name (its folder in ``rmpl/weights/``).
        joints: the joint set it answers in, "coco17" or "halpe26".
        floor: it reads the floor plane (``--floor``).
        time: it lifts whole tracks (needs a frame rate); else each frame.
        summary: what it is, in a few words.
        selected_on: the rule and data it was selected on (docs/results.md).
        figures: its headline figures (docs/results.md has the commands).
        picked: when ``rmpl run`` picks it without ``--model`` (:func:`choose_model`).
    """

    name: str
    joints: str
    floor: bool
    time: bool
    summary: str
    selected_on: str
    figures: str
    picked: str

    @property
    def path(self) -> Path:
        return WEIGHTS / self.name

    def size_mb(self) -> float:
        """The size of its files, MB (0 when the weights are not installed)."""
        files = [p for p in self.path.glob("*") if p.is_file()]
        return sum(p.stat().st_size for p in files) / 1e6


#: ``rmpl run``'s choice without ``--model`` (:func:`choose_model`): per frame with two or
#: more cameras, whole tracks with two or more cameras and a frame rate, one camera with a
#: floor, one camera without.
PER_FRAME, TEMPORAL, ONE_CAMERA, ONE_CAMERA_NO_FLOOR = "floor26", "temporal26", "floor26", "default"

MODELS: tuple[ShippedModel, ...] = (
    ShippedModel(
        "floor26", "halpe26", True, False,
        "halpe26 fine-tuned with the floor plane as an input and many one-view batches",
        "held-out renders, one view with the floor given, and Shelf per frame, by a rule "
        "written before the runs",
        "see docs/results.md, one camera and accuracy by number of cameras",
        "per frame: two or more cameras without a frame rate; one camera with a floor",
    ),
    ShippedModel(
        "temporal26", "halpe26", False, True,
        "whole tracks, HALPE-26, on halpe26's per-frame model, with a per-joint error radius",
        "Shelf through rmpl run against the per-frame model, by a rule written before the "
        "runs",
        "see docs/results.md, accuracy by number of cameras",
        "two or more cameras and a frame rate",
    ),
    ShippedModel(
        "default", "coco17", False, False,
        "per frame, COCO-17, the best on the joints the detector sees",
        "synthetic held-out rigs and Shelf (COCO-17)",
        "see docs/results.md, the thesis's tables",
        "one camera without a floor; rmpl evaluate's rmpl and Lifter.from_pretrained()",
    ),
    ShippedModel(
        "halpe26", "halpe26", False, False,
        "default fine-tuned on anny bodies: COCO-17 + head top, neck, mid-hip and feet",
        "held-out HALPE-26 renders (feet) and Shelf (COCO-17 within 1 mm)",
        "see docs/results.md, feet and OpenSim",
        "never (opt-in)",
    ),
    ShippedModel(
        "occlusion", "coco17", False, False,
        "default's recipe with more keypoint removal in training (p=0.4)",
        "Shelf with keypoints dropped",
        "see docs/results.md, under occlusion",
        "never (opt-in)",
    ),
    ShippedModel(
        "scenes26", "halpe26", False, False,
        "halpe26 fine-tuned with multi-person scenes as well",
        "held-out multi-person scenes",
        "see docs/results.md, several people",
        "never (opt-in)",
    ),
    ShippedModel(
        "temporal", "coco17", False, True,
        "whole tracks, COCO-17, on default's per-frame model",
        "Shelf through rmpl run against the per-frame model",
        "see docs/results.md, accuracy by number of cameras",
        "never (opt-in)",
    ),
)  # fmt: skip

#: Per-frame shipped models by name -> their folder.
PRETRAINED: dict[str, Path] = {m.name: m.path for m in MODELS if not m.time}
#: Temporal (whole-track) shipped models by name -> their folder.
PRETRAINED_TEMPORAL: dict[str, Path] = {m.name: m.path for m in MODELS if m.time}


def choose_model(
    cameras: int,
    fps: float | None = None,
    method: str = "rmpl",
    whole_tracks: bool = True,
    floor_known: bool = True,
) -> str:
    """``rmpl run``'s (and ``rmpl lift``'s) model when ``--model`` is not given.

    With two or more cameras: the temporal model when lifting whole tracks with a known
    frame rate (a warning when the frame rate is unknown), else the per-frame one. With one
    camera: the floor-reading model given a floor, else the COCO-17 ``default`` with the
    body-size prior (the floor model was chosen with the floor given). Each was chosen by a
    rule set before the runs (docs/results.md).

    Args:
        cameras: the number of cameras of the run.
        fps: its frame rate, or None.
        method: "rmpl", or a triangulation (the model is then unused).
        whole_tracks: ``rmpl run`` (True) or ``rmpl lift`` (False: per frame).
        floor_known: with one camera, whether a floor is known.
    """
    if cameras < 2:
        return ONE_CAMERA if floor_known else ONE_CAMERA_NO_FLOOR
    if method != "rmpl" or not whole_tracks:
        return PER_FRAME
    if fps is None:
        log.warning(
            "no frame rate known (give --fps): lifting each frame with the per-frame model "
            "instead of whole tracks with the temporal model"
        )
        return PER_FRAME
    return TEMPORAL


def _config(name_or_path: str | Path) -> dict | None:
    """A ``--model`` value's ``config.json`` (shipped name or checkpoint folder), or None."""
    name = str(name_or_path)
    path = Path(PRETRAINED.get(name) or PRETRAINED_TEMPORAL.get(name) or name_or_path)
    try:
        meta = json.loads((path / "config.json").read_text())
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def is_temporal_checkpoint(name_or_path: str | Path) -> bool:
    """Whether a ``--model`` value names a temporal model (shipped name or checkpoint)."""
    meta = _config(name_or_path)
    return meta is not None and meta.get("format") == "rmpl-temporal-checkpoint-1"


def checkpoint_reads_floor(name_or_path: str | Path) -> bool:
    """Whether a ``--model`` value (shipped name or checkpoint directory) names a model whose
    per-frame model takes the floor as an input (``RMPLConfig.floor``; a temporal model's
    too); False when unreadable."""
    meta = _config(name_or_path)
    model = meta.get("model") if meta is not None else None
    return isinstance(model, dict) and bool(model.get("floor", False))


#: ``--model`` help of the commands that lift.
MODEL_HELP = (
    "shipped model ("
    + "; ".join(f"{m.name}: {m.summary}" + (", reads the floor (--floor)" if m.floor else "")
                + (", needs a frame rate" if m.time else "") for m in MODELS)
    + "; rmpl models lists them) or checkpoint folder"
)  # fmt: skip
