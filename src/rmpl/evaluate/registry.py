"""Every method ``rmpl evaluate --methods`` names: per frame (:data:`rmpl.evaluate.methods.METHODS`)
and over sequences (:data:`rmpl.evaluate.sequences.SEQUENCE_METHODS`)."""

from __future__ import annotations

from rmpl.errors import InputError
from rmpl.evaluate.methods import METHODS, Method, _spec_parts, make_method
from rmpl.evaluate.sequences import SEQUENCE_METHODS, is_sequence_method, make_sequence_method

__all__ = ["parse_methods"]


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
    for name in names:
        if _spec_parts(name)[0] not in METHODS and not is_sequence_method(name):
            accepted = ", ".join([*METHODS, *SEQUENCE_METHODS])
            raise InputError(None, "--methods", f"methods among {accepted} (rmpl:MODEL)", name)
    return {
        name: make_sequence_method(name) if is_sequence_method(name) else make_method(name)
        for name in names
    }
