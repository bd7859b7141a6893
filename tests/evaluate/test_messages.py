"""Option values are named in messages, with plain numbers (0.0, never np.float64(0.0))."""

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.evaluate.harness import EvalConfig
from rmpl.evaluate.heldout import heldout_view_errors
from rmpl.evaluate.methods import METHODS
from rmpl.evaluate.registry import parse_methods


def test_unknown_method_names_the_option_and_the_accepted_values():
    with pytest.raises(InputError) as e:
        parse_methods("triangulate,magic")
    msg = str(e.value)
    assert "'--methods'" in msg and "magic" in msg
    assert all(name in msg for name in METHODS)


def test_methods_in_order_and_each_once():
    assert list(parse_methods("robust, triangulate")) == ["robust", "triangulate"]
    with pytest.raises(InputError, match="each method once"):
        parse_methods("robust,robust")
    with pytest.raises(InputError, match="at least one"):
        parse_methods(" , ")


@pytest.mark.parametrize(
    "kwargs",
    [
        {"dropout": tuple(np.array([0.0, 1.0]))},
        {"calib_noise": (np.float64(0.0), np.float64(0.0))},
    ],
)
def test_config_messages_print_plain_numbers(kwargs):
    with pytest.raises(ValueError) as e:
        EvalConfig(**kwargs)
    assert "np.float64" not in str(e.value) and "0.0" in str(e.value)


def test_heldout_view_count_message_prints_plain_numbers():
    from rmpl.geometry.camera import Camera, Rig

    K = np.array([[1000.0, 0, 500], [0, 1000, 500], [0, 0, 1]])
    rig = Rig(tuple(Camera(K, np.eye(3), np.array([i, 0, 5.0]), name=str(i)) for i in range(3)))
    kp, sc = np.zeros((1, 3, 17, 2)), np.ones((1, 3, 17))
    with pytest.raises(ValueError) as e:
        heldout_view_errors(kp, sc, rig, {}, np.array([5]))
    assert "np.int64" not in str(e.value) and "[5]" in str(e.value)
