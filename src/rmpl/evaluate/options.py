"""``rmpl evaluate``'s option values, parsed and checked once, with errors naming the option.

Shared by every protocol: number lists (``--dropout``, ``--heights``), the calibration noise
(``--calib-noise DEG,MM``), the :class:`rmpl.evaluate.harness.EvalConfig` they make, and
the refusal of options a protocol cannot use.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from rmpl.errors import InputError
from rmpl.evaluate.harness import EvalConfig

__all__ = ["check_min_score", "eval_config", "parse_calib_noise", "parse_floats", "refuse"]


def parse_floats(text: str, option: str) -> list[float]:
    """Comma-separated finite numbers, e.g. ``0,0.2,0.4``.

    Raises:
        InputError: a word that is not a number, or no number, or a NaN / infinity.
    """
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(None, option, "comma-separated numbers", text) from None
    if not values or not all(np.isfinite(values)):
        raise InputError(None, option, "comma-separated finite numbers", text)
    return values


def parse_calib_noise(text: str | None) -> tuple[float, float] | None:
    """``--calib-noise DEG,MM`` -> (degrees, metres), or None when not given."""
    if text is None:
        return None
    values = parse_floats(text, "--calib-noise")
    if len(values) != 2:
        raise InputError(None, "--calib-noise", "DEG,MM (two numbers)", text)
    return values[0], values[1] / 1000.0


def eval_config(
    dropout: str,
    calib_noise: str | None,
    calib_reps: int,
    seed: int,
    pck_mm: float,
    fps: float = 25.0,
) -> EvalConfig:
    """The perturbations and thresholds from their option strings (``--pck`` in mm)."""
    return EvalConfig(
        fps=fps,
        dropout=tuple(parse_floats(dropout, "--dropout")),
        calib_noise=parse_calib_noise(calib_noise),
        calib_reps=calib_reps,
        seed=seed,
        pck_threshold=pck_mm / 1000.0,
    )


def refuse(given: Iterable[tuple[str, object]], why: str) -> None:
    """Refuse the first option given (value not None) that cannot apply.

    Args:
        given: (option, value or None) pairs, checked in order.
        why: completes "no OPTION ...", e.g. "with --dataset recording".

    Raises:
        InputError: naming the option and its value.
    """
    for option, value in given:
        if value is not None:
            raise InputError(None, option, f"no {option} {why}", value)


def check_min_score(value: float) -> float:
    """``--min-score``: a confidence in (0, 1]."""
    if not (np.isfinite(value) and 0 < value <= 1):
        raise InputError(None, "--min-score", "a confidence in (0, 1]", value)
    return value
