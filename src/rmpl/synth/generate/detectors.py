"""The generator's 2D detectors: by name (its own, ``rmpl run``'s, or ``module:factory``),
their options checked, run on renders.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import logging

import numpy as np

from rmpl.errors import InputError

log = logging.getLogger(__name__)


def make_detector(name: str, options: dict | None = None):
    """A detector from :data:`~rmpl.synth.detect.DETECTORS`, from ``rmpl run``'s
    :data:`~rmpl.pipeline.detect2d.DETECTORS` (e.g. ``blazepose-multi``), or a
    ``module:factory`` spec, built with the keyword arguments ``options``."""
    check_detector_options(name, options)
    return _detector_factory(name)(**(options or {}))


def _detector_factory(name: str):
    """The callable :func:`make_detector` calls for detector ``name``."""
    from rmpl.pipeline.detect2d import DETECTORS as RUN_DETECTORS
    from rmpl.synth.detect import DETECTORS

    if name in DETECTORS:
        return DETECTORS[name]
    if name in RUN_DETECTORS:
        return RUN_DETECTORS[name]
    if ":" in name:
        import importlib

        module, attr = name.split(":", 1)
        return getattr(importlib.import_module(module), attr)
    known = sorted(set(DETECTORS) | set(RUN_DETECTORS))
    raise ValueError(f"unknown detector {name!r}; known: {known} or 'module:factory'")


#: ``rmpl run``'s detectors whose factories only pass keyword arguments on: the class
#: whose constructor ``detector_options`` are checked against.
_OPTION_CLASSES = {
    "blazepose-multi": ("rmpl.synth.detect_multi", "BlazePoseMulti"),
    "blazepose-multi-static": ("rmpl.synth.detect_multi", "BlazePoseMulti"),
    "movenet": ("rmpl.synth.detect_movenet", "MoveNet"),
    "movenet-blazepose": ("rmpl.synth.detect_movenet", "MoveNetBlazePose"),
    "movenet-blazepose-static": ("rmpl.synth.detect_movenet", "MoveNetBlazePose"),
}


def check_detector_options(name: str, options: dict | None, path=None) -> None:
    """Check ``detector_options`` against detector ``name``'s constructor (by name only,
    nothing is built; its values are checked when it is built).

    Raises:
        InputError: an option the constructor does not take (field ``detector_options``);
            a constructor that takes any ``**kwargs`` accepts every name.
    """
    if not options:
        return
    import functools
    import importlib
    import inspect

    if name in _OPTION_CLASSES:
        module, attr = _OPTION_CLASSES[name]
        target = getattr(importlib.import_module(module), attr)
    else:
        target = _detector_factory(name)
        if isinstance(target, functools.partial):
            target = target.func
    params = inspect.signature(target).parameters.values()
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return
    takes = [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    unknown = sorted(set(options) - set(takes))
    if unknown:
        raise InputError(
            path,
            "detector_options",
            f"keyword arguments of detector {name!r}: some of {takes}",
            f"{unknown} (not taken)",
        )


def follows(detector) -> bool:
    """Whether ``detector`` follows people from image to image (it has ``reset``, like
    :class:`rmpl.synth.detect.MultiPersonDetector`; ``track=False`` turns that off)."""
    return callable(getattr(detector, "reset", None)) and getattr(detector, "track", True)


def detect_person(detector, images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The detector's most confident person in each image (one body per scene).

    A single-person detector's output is returned as it is; a detector with a people axis
    gives, per image, the slot with the largest summed score (others are phantoms or
    nobody).

    Returns:
        keypoints (B, 17, 2) pixels, NaN = missed; scores (B, 17).
    """
    from rmpl.synth.detect import max_people, with_people_axis

    kp, sc = detector(images)
    if max_people(detector) == 1:
        return np.asarray(kp), np.asarray(sc)
    kp, sc = with_people_axis(detector, kp, sc, len(images))  # (B, N, J, 2), (B, N, J)
    best = sc.sum(-1).argmax(-1)  # (B,)
    rows = np.arange(len(images))
    return kp[rows, best], sc[rows, best]


def in_joint_set(detector, kp: np.ndarray, sc: np.ndarray, joints: str):
    """A detector's keypoints (..., J_det, 2) and scores (..., J_det) in joint set
    ``joints`` (:func:`rmpl.skeleton.to_joint_set`)."""
    from rmpl.skeleton import to_joint_set

    return to_joint_set(kp, sc, detector.skeleton, joints)
