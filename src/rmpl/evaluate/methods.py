"""The 3D methods compared: name -> ``fn(keypoints, scores, rig) -> points``.

A method maps per-person multi-view keypoints ``(N, V, J, 2)`` pixels + scores ``(N, V, J)``
and a rig of ``V`` cameras to COCO-17 joints ``(N, J, 3)`` metres, NaN where it gives no
estimate. A new method plugs in as one entry of :data:`METHODS`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry import Rig, triangulate, triangulate_robust
from rmpl.skeleton import COCO17

__all__ = ["METHODS", "Method", "make_method", "parse_methods"]

Method = Callable[[np.ndarray, np.ndarray, Rig], np.ndarray]


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
        ok = (sc > 0) & np.isfinite(kp).all(-1)
        if not ok.any():  # nothing to lift; the lifter would refuse
            return np.full((*kp.shape[:-3], kp.shape[-2], 3), np.nan)
        return lifter.lift(kp, sc, rig).points

    return run


METHODS: dict[str, Callable[[str], Method]] = {
    "triangulate": lambda _: _nan_if_too_few_views(
        lambda kp, sc, rig: triangulate(kp, sc, rig).points
    ),
    "robust": lambda _: _nan_if_too_few_views(
        lambda kp, sc, rig: triangulate_robust(kp, sc, rig, swap_pairs=COCO17.flip_pairs).points
    ),
    "rmpl": _rmpl,
}


def make_method(spec: str) -> Method:
    """A method from ``name`` or ``name:argument`` (e.g. ``rmpl:runs/x``).

    Raises:
        ValueError: an unknown name.
    """
    name, _, arg = spec.partition(":")
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)}")
    return METHODS[name](arg)


def parse_methods(spec: str) -> dict[str, Method]:
    """``--methods``: comma-separated method specs -> name -> method, in the given order.

    Raises:
        InputError: no method, a repeated method, or an unknown name.
    """
    names = [m.strip() for m in spec.split(",") if m.strip()]
    if not names:
        raise InputError(None, "--methods", "at least one method", spec)
    if len(set(names)) != len(names):
        raise InputError(None, "--methods", "each method once", spec)
    from rmpl.evaluate.sequences import (
        SEQUENCE_METHODS,
        is_sequence_method,
        make_sequence_method,
    )

    for name in names:
        if name.partition(":")[0] not in METHODS and not is_sequence_method(name):
            accepted = ", ".join([*METHODS, *SEQUENCE_METHODS])
            raise InputError(None, "--methods", f"methods among {accepted} (rmpl:MODEL)", name)
    return {
        name: make_sequence_method(name) if is_sequence_method(name) else make_method(name)
        for name in names
    }
