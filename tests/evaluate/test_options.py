"""Option parsing of rmpl evaluate: every bad value is one InputError naming its option."""

import pytest

from rmpl.errors import InputError
from rmpl.evaluate.experiments import synthetic_view_counts
from rmpl.evaluate.options import check_min_score, parse_calib_noise, parse_floats, refuse
from rmpl.evaluate.protocols import recording_view_counts


def test_parse_floats_and_calib_noise():
    assert parse_floats("0, 0.2,0.4", "--dropout") == [0.0, 0.2, 0.4]
    for bad in ("a,1", "", "nan", "1,inf"):
        with pytest.raises(InputError, match="--dropout"):
            parse_floats(bad, "--dropout")
    assert parse_calib_noise(None) is None
    assert parse_calib_noise("2,20") == (2.0, 0.02)  # millimetres in, metres out
    with pytest.raises(InputError, match="two numbers"):
        parse_calib_noise("2")


def test_refuse_names_the_first_given_option():
    refuse([("--a", None), ("--b", None)], "here")  # nothing given: nothing refused
    with pytest.raises(InputError) as e:
        refuse([("--a", None), ("--b", "x"), ("--c", "y")], "with --poses")
    assert "'--b'" in str(e.value) and "no --b with --poses" in str(e.value)


@pytest.mark.parametrize("value", [0.0, -1.0, 1.5, float("nan")])
def test_min_score_outside_0_1_is_refused(value):
    with pytest.raises(InputError, match="--min-score"):
        check_min_score(value)
    assert check_min_score(1.0) == 1.0


def test_view_counts():
    assert synthetic_view_counts(None) == [1, 2, 3, 4, 5]
    assert synthetic_view_counts("pairs,4") == [2, 4]
    with pytest.raises(InputError, match="--views"):
        synthetic_view_counts("0")
    assert recording_view_counts(None, 4) == [1, 2, 3]
    assert recording_view_counts("3,1,3", 4) == [1, 3]
    for bad in ("4", "x", ","):
        with pytest.raises(InputError, match="--views"):
            recording_view_counts(bad, 4)
