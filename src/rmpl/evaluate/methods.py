"""The 3D methods compared: name -> ``fn(keypoints, scores, rig) -> points``.

A method maps per-person multi-view keypoints ``(N, V, J, 2)`` pixels + scores ``(N, V, J)``
and a rig of ``V`` cameras to joints ``(N, J', 3)`` metres, NaN where it gives no estimate:
COCO-17 (``J' = 17``) or HALPE-26 (``J' = 26``, a lifter that outputs it; its first 17
joints are COCO-17, the scored ones). A new method plugs in as one entry of :data:`METHODS`.

The 2D is COCO-17 or HALPE-26 (:data:`INPUT_SETS`, by joint count). The triangulation
baselines use its COCO-17 joints (the first 17); a lifter takes the joints its model knows
(:func:`fit_input`).

``rmpl+floor[:CUES][@MODEL]`` (:class:`MonocularMethod`) is the single-view lifting of
:mod:`rmpl.pipeline.monocular`: the shipped lifter (or MODEL), then depth from the floor,
the body-size prior and (with "time") whole tracks; CUES is any of floor, size, time joined
by + (default all three), or "none" (the lifter's own depth). A MODEL that reads the floor
(``rmpl+floor:time@floor26``) is given it, in one view and in more. With two or more views
it is the plain lifter. A temporal MODEL that reads the floor lifts each one-view track
whole (it needs the time cue and a dataset in time). Its floor is set by ``rmpl evaluate --floor``
(:attr:`MonocularMethod.floor`). Its poses have the model's joints (the cues read the
COCO-17 ones and the depth moves all).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry import Rig, triangulate, triangulate_robust
from rmpl.skeleton import COCO17, HALPE26

if TYPE_CHECKING:
    from rmpl.pipeline.monocular import MonocularConfig

__all__ = [
    "INPUT_SETS",
    "METHODS",
    "Method",
    "MonocularMethod",
    "fit_input",
    "make_method",
    "stretches",
]

Method = Callable[[np.ndarray, np.ndarray, Rig], np.ndarray]

#: The 2D joint sets the methods take, by joint count; both start with COCO-17.
INPUT_SETS = {COCO17.num_joints: COCO17.name, HALPE26.num_joints: HALPE26.name}


def fit_input(kp: np.ndarray, sc: np.ndarray, num_joints: int) -> tuple[np.ndarray, np.ndarray]:
    """2D (*, J, 2) + scores (*, J) for a model of ``num_joints`` outputs: HALPE-26 2D for a
    COCO-17 model becomes its first 17 joints; otherwise the 2D is unchanged (a HALPE-26
    model embeds COCO-17 2D itself, :func:`rmpl.skeleton.to_model_joints`).

    Raises:
        ValueError: 2D whose joint count is not one of :data:`INPUT_SETS`.
    """
    J = kp.shape[-2]
    if J not in INPUT_SETS:
        raise ValueError(f"2D with {J} joints: expected one of {sorted(INPUT_SETS)}")
    if J > num_joints == COCO17.num_joints:
        return kp[..., : COCO17.num_joints, :], sc[..., : COCO17.num_joints]
    return kp, sc


def _coco_input(fn: Method) -> Method:
    """A triangulation baseline on the COCO-17 joints (the first 17) of the 2D."""

    def run(kp: np.ndarray, sc: np.ndarray, rig: Rig) -> np.ndarray:
        return fn(kp[..., : COCO17.num_joints, :], sc[..., : COCO17.num_joints], rig)

    return run


def _nan_if_too_few_views(fn: Method) -> Method:
    """Triangulation needs two views: with one, every joint is NaN (counted as missing)."""

    def run(kp: np.ndarray, sc: np.ndarray, rig: Rig) -> np.ndarray:
        if len(rig) < 2:
            return np.full((*kp.shape[:-3], kp.shape[-2], 3), np.nan)
        return fn(kp, sc, rig)

    return run


def _rmpl(spec: str) -> Method:
    from rmpl.inference import Lifter

    lifter = Lifter.from_pretrained(spec or "default")

    def run(kp: np.ndarray, sc: np.ndarray, rig: Rig) -> np.ndarray:
        kp, sc = fit_input(kp, sc, lifter.num_joints)
        ok = (sc > 0) & np.isfinite(kp).all(-1)
        if not ok.any():  # nothing to lift; the lifter would refuse
            return np.full((*kp.shape[:-3], lifter.num_joints, 3), np.nan)
        return lifter.lift(kp, sc, rig).points

    return run


class MonocularMethod:
    """``rmpl+floor[:CUES]``: one view lifted with depth cues; ``rmpl`` with more views.

    With the "time" cue it is a sequence method (``sequence`` is True): the harness passes
    every person of a stretch of frames, which are tracked as ``rmpl run`` does
    (:func:`rmpl.pipeline.monocular.lift_stretch`). Called per frame (``fn(kp, sc, rig)``,
    as the synthetic scenes do), it uses the floor and size cues only.

    Args:
        cues: the depth cues, e.g. "floor+size" ("" = all).
        model: the per-frame model, a shipped name or a checkpoint directory; or a temporal
            model that reads the floor, whose per-frame model lifts and tracks each stretch
            before it lifts each one-view track as a whole (as ``rmpl run`` with one camera).

    Attributes:
        floor: the :class:`rmpl.geometry.floor.Floor`, or None: the calibration convention
            of the rig (:func:`rmpl.geometry.floor.convention_floor`) if it has one.
        floor_rule: "convention" (None means the rig's convention) or "none" (no floor).
    """

    def __init__(self, cues: str = "", model: str = "default") -> None:
        from rmpl.inference import Lifter
        from rmpl.inference_temporal import is_temporal_checkpoint
        from rmpl.pipeline.monocular import MonocularConfig

        cues, _, named = cues.partition("@")
        self._model = named or model
        self._cues = cues
        if cues:
            MonocularConfig.from_cues(cues)  # a bad spec fails here, not at the first frame
        self.floor = None
        self.floor_rule = "convention"
        self._temporal = None
        if is_temporal_checkpoint(self._model):
            from rmpl.inference_temporal import TemporalLifter

            self._temporal = TemporalLifter.from_pretrained(self._model)
            if not self._temporal.reads_floor:
                raise InputError(None, "--methods", "rmpl+floor with a temporal model that "
                                 "reads the floor (or a per-frame model)", self._model)  # fmt: skip
            if "time" not in self.config.cues:
                got = f"rmpl+floor:{cues}@{self._model}"
                raise InputError(None, "--methods", "the time cue with a temporal model (it "
                                 "lifts whole tracks)", got)  # fmt: skip
            self._lifter = Lifter(self._temporal.model.frame_model, {})
        else:
            self._lifter = Lifter.from_pretrained(self._model)

    def config_for(self, floor_known: bool) -> MonocularConfig:
        """The cues given, or ``rmpl run``'s for the model with or without a floor
        (:meth:`rmpl.pipeline.monocular.MonocularConfig.for_model`)."""
        from rmpl.pipeline.monocular import MonocularConfig

        run = MonocularConfig.for_model(self._model, floor_known=floor_known)
        if not self._cues:
            return run
        return MonocularConfig.from_cues(self._cues, lifter_sd=run.lifter_sd)

    @property
    def config(self) -> MonocularConfig:
        """The cues with a known floor (:meth:`config_for`; with or without one, they
        include "time" alike)."""
        return self.config_for(floor_known=True)

    @property
    def sequence(self) -> bool:
        return "time" in self.config.cues

    def _floor(self, rig: Rig):
        from rmpl.geometry.floor import check_floor, convention_floor

        if self.floor is not None:
            return check_floor(self.floor, rig.centers)
        if self.floor_rule == "none":
            return None
        return convention_floor(rig.R, rig.centers)

    def _lift_fn(self, up, floor=None):
        """The lifter for :mod:`rmpl.pipeline.monocular`: poses in the model's joints."""
        lifter = self._lifter

        def fn(kp, sc, rig):
            r = lifter.lift(*fit_input(kp, sc, lifter.num_joints), rig, up=up, floor=floor)
            return r.points, r.num_views

        return fn

    def _multi_view(self, kp, sc, rig) -> np.ndarray:
        """More than one view: the plain lifter, the model's own joints (a model that reads
        the floor is given it)."""
        kp, sc = fit_input(kp, sc, self._lifter.num_joints)
        floor = self._floor(rig) if self._lifter.reads_floor else None
        return self._lifter.lift(kp, sc, rig, floor=floor).points

    def __call__(self, kp, sc, *rest):
        """``(kp, sc, rig)`` per frame, or the sequence signature of
        :class:`rmpl.evaluate.sequences.SequenceMethod`."""
        from dataclasses import replace

        from rmpl.pipeline.monocular import lift_stretch, monocular_people

        if len(rest) == 1:  # per frame
            if self._temporal is not None:  # its cues hold "time": the harness runs it in time
                raise ValueError("rmpl+floor with a temporal model lifts sequences only")
            rig = rest[0]
            if not ((sc > 0) & np.isfinite(kp).all(-1)).any():
                return np.full((*kp.shape[:-3], self._lifter.num_joints, 3), np.nan)
            if len(rig) > 1:
                return self._multi_view(kp, sc, rig)
            floor = self._floor(rig)
            up = None if floor is None else floor.n
            cfg = self.config_for(floor is not None)
            cfg = replace(cfg, cues=tuple(c for c in cfg.cues if c != "time"))
            frame = np.arange(len(kp))
            res = monocular_people(kp, sc, frame, len(kp), rig, None, floor, cfg,
                                   lift=self._lift_fn(up, floor))  # fmt: skip
            return res.points[:, 0]
        frame, num_frames, rig, fps = rest[:4]
        if len(rig) > 1:  # every view: the plain lifter, per frame
            return self._multi_view(kp, sc, rig), frame
        floor = self._floor(rig)
        up = None if floor is None else floor.n
        preds, at = [np.zeros((0, self._lifter.num_joints, 3))], [np.zeros(0, int)]
        fn = self._lift_fn(up, floor)
        for a, b, step in stretches(num_frames, *rest[4:6]):
            rows = (frame >= a) & (frame < b)
            if rows.any():
                p, t = lift_stretch(
                    kp[rows], sc[rows], frame[rows] - a, b - a, rig, fps / step, floor,
                    self.config_for(floor is not None), lift=fn, temporal=self._temporal,
                )  # fmt: skip
                preds.append(p)
                at.append(t + a)
        return np.concatenate(preds), np.concatenate(at)


METHODS: dict[str, Callable[[str], Method]] = {
    "triangulate": lambda _: _coco_input(
        _nan_if_too_few_views(lambda kp, sc, rig: triangulate(kp, sc, rig).points)
    ),
    "robust": lambda _: _coco_input(
        _nan_if_too_few_views(
            lambda kp, sc, rig: triangulate_robust(kp, sc, rig, swap_pairs=COCO17.flip_pairs).points
        )
    ),
    "rmpl": _rmpl,
    "rmpl+floor": MonocularMethod,
}


def _spec_parts(spec: str) -> tuple[str, str, str]:
    """``name:arg``, or ``name@MODEL`` (``rmpl+floor@floor26``) as ``name``, ``:``, ``@MODEL``."""
    if "@" in spec and ":" not in spec:
        name, _, model = spec.partition("@")
        return name, ":", "@" + model
    return spec.partition(":")


def make_method(spec: str) -> Method:
    """A method from ``name`` or ``name:argument`` (e.g. ``rmpl:runs/x``).

    Raises:
        ValueError: an unknown name.
    """
    name, _, arg = _spec_parts(spec)
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)}")
    return METHODS[name](arg)


def stretches(num_frames: int, frame_numbers=None, clips=None) -> list[tuple[int, int, int]]:
    """Continuous stretches [a, b) of a part's frames with their frame step: a new stretch
    starts at a new clip or where the numbering jumps by other than the usual step.

    >>> stretches(6, np.array([0, 1, 2, 10, 11, 12]))
    [(0, 3, 1), (3, 6, 1)]
    >>> stretches(4, np.array([0, 5, 10, 15]))
    [(0, 4, 5)]
    """
    if frame_numbers is None or num_frames < 2:
        return [(0, num_frames, 1)] if num_frames else []
    f = np.asarray(frame_numbers)
    d = np.diff(f)
    step = int(np.median(d)) if len(d) else 1
    cut = d != step
    if clips is not None:
        c = np.asarray(clips)
        cut |= c[1:] != c[:-1]
    starts = np.r_[0, np.flatnonzero(cut) + 1]
    ends = np.r_[starts[1:], num_frames]
    return [(int(a), int(b), max(step, 1)) for a, b in zip(starts, ends, strict=True)]
