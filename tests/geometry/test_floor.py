"""The floor plane: parsing, checks against the cameras, the convention, fitting."""

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.geometry.floor import (
    Floor,
    check_floor,
    convention_floor,
    fit_floor,
    parse_floor,
    signed_distance,
)

CAMERAS = np.array([[3.0, 0.0, 2.5], [-3.0, 1.0, 1.2]])  # z up, above z = 0


@pytest.mark.parametrize(
    "text, normal, height",
    [
        ("z=0", (0, 0, 1), 0.0),
        ("z=-0.05", (0, 0, 1), -0.05),
        ("-y=0", (0, -1, 0), 0.0),
        ("-y=1.5", (0, -1, 0), 1.5),  # n . X = 1.5 with n = -y: the plane y = -1.5
        ("0,0,2,1", (0, 0, 1), 0.5),  # normalised: 2z = 1 is z = 0.5
        (" 0, 0.6, 0.8, 0 ", (0, 0.6, 0.8), 0.0),
    ],
)
def test_parse_floor_forms(text, normal, height):
    f = parse_floor(text)
    assert np.allclose(f.normal, normal) and f.height == pytest.approx(height)
    assert f.source.startswith("--floor")


@pytest.mark.parametrize("text", ["z", "w=0", "z=up", "0,0,1", "0,0,0,1", "nan,0,1,0", "0,0,1,inf"])
def test_parse_floor_refuses_what_is_not_a_plane(text):
    with pytest.raises(InputError) as e:
        parse_floor(text)
    assert "--floor" in str(e.value) and ("plane" in str(e.value) or "AXIS=H" in str(e.value))


def test_signed_distance_and_scale_of_units():
    f = parse_floor("z=0.1")
    d = signed_distance(np.array([[0, 0, 1.1], [5, 5, 0.0]]), f)
    assert np.allclose(d, [1.0, -0.1])


def test_check_floor_refuses_a_floor_above_every_camera():
    with pytest.raises(InputError) as e:
        check_floor(parse_floor("z=3"), CAMERAS)
    msg = str(e.value)
    assert "--floor" in msg and "below the cameras" in msg and "camera heights" in msg
    with pytest.raises(InputError):  # the normal pointing down puts the cameras below
        check_floor(parse_floor("-z=0"), CAMERAS)
    assert check_floor(parse_floor("z=2"), CAMERAS).height == 2  # one camera above is enough


def test_check_floor_refuses_a_bad_normal():
    with pytest.raises(InputError, match="unit floor normal"):
        check_floor(Floor((0.0, 0.0, 2.0), 0.0), CAMERAS)
    with pytest.raises(InputError, match="unit floor normal"):
        check_floor(Floor((np.nan, 0.0, 1.0), 0.0), CAMERAS)
    with pytest.raises(InputError, match="finite floor height"):
        check_floor(Floor((0.0, 0.0, 1.0), float("nan")), CAMERAS)


def _camera(eye, target=(0.0, 0.0, 1.0), up=(0.0, 0.0, 1.0), roll=0.0):
    from rmpl.geometry.camera import look_at, rodrigues

    R, _ = look_at(np.asarray(eye, float), np.asarray(target, float), np.asarray(up, float))
    return rodrigues(np.array([0, 0, np.radians(roll)])) @ R  # roll about the optical axis


def test_convention_needs_upright_cameras_above_an_axis():
    R = np.stack([_camera(c) for c in CAMERAS])
    f = convention_floor(R, CAMERAS)
    assert f is not None and f.normal == (0.0, 0.0, 1.0) and f.height == 0
    assert "convention" in f.source
    one = _camera([4.0, 0, 3.5])  # one camera looking down 28 degrees: still upright
    assert convention_floor(one[None], np.array([[4.0, 0, 3.5]])).normal == (0.0, 0.0, 1.0)
    assert convention_floor(_camera([4.0, 0, 3.5], roll=20)[None], np.array([[4.0, 0, 3.5]]))
    rolled = _camera([4.0, 0, 3.5], roll=40)
    assert convention_floor(rolled[None], np.array([[4.0, 0, 3.5]])) is None
    assert convention_floor(R, -CAMERAS) is None  # cameras below z = 0
    y_down = _camera([0, -2.0, 4.0], target=(0, -1.0, 0), up=(0, -1.0, 0))  # Panoptic-like
    f = convention_floor(y_down[None], np.array([[0, -2.0, 4.0]]))
    assert f.normal == (0.0, -1.0, 0.0)
    assert convention_floor(R, CAMERAS, up=np.array([0, 0, 1.0])).normal == (0.0, 0.0, 1.0)


def test_fit_floor_level_is_robust_to_lifted_ankles():
    rng = np.random.default_rng(0)
    n = 200
    pts = np.c_[rng.uniform(-2, 2, (n, 2)), 0.07 + rng.normal(0, 0.01, n)]  # ankles on z=0
    pts[:30, 2] += rng.uniform(0.2, 0.6, 30)  # a few jumps and swings
    pts[5] = np.nan
    f = fit_floor(pts, np.array([0, 0, 1.0]), contact_height=0.07)
    assert abs(f.height) < 0.02 and np.allclose(f.normal, (0, 0, 1), atol=0.02)
    assert 0 < f.spread < 0.05 and "estimated from 199" in f.source


def test_fit_floor_finds_a_tilted_floor_and_keeps_up_without_spread():
    rng = np.random.default_rng(1)
    tilt = np.radians(4)
    true_n = np.array([np.sin(tilt), 0, np.cos(tilt)])
    xy = rng.uniform(-3, 3, (300, 2))
    z = (0.5 - true_n[0] * xy[:, 0]) / true_n[2] + rng.normal(0, 0.005, 300)
    f = fit_floor(np.c_[xy, z], np.array([0, 0, 1.0]), contact_height=0.0)
    assert np.degrees(np.arccos(np.dot(f.normal, true_n))) < 0.5
    assert f.height == pytest.approx(0.5, abs=0.01)
    line = np.c_[np.linspace(-2, 2, 50), np.zeros(50), np.full(50, 0.07)]  # one walking line
    assert fit_floor(line, np.array([0, 0, 1.0])).normal == (0.0, 0.0, 1.0)


def test_fit_floor_needs_points():
    with pytest.raises(InputError, match="at least 10"):
        fit_floor(np.full((30, 3), np.nan), np.array([0, 0, 1.0]))


def test_an_overhead_camera_gives_no_convention_floor():
    """Looking straight down, any world axis is 'upright' by roll: no floor is assumed."""
    from rmpl.geometry.camera import look_at

    for target in ([0.0, 0.01, 0.0], [0.01, 0.0, 0.0]):  # straight down, two headings
        R, _ = look_at(np.array([0.0, 0.0, 3.0]), np.array(target))
        assert convention_floor(R[None], np.array([[0.0, 0.0, 3.0]])) is None
    R, _ = look_at(np.array([5.0, 0.0, 2.5]), np.array([0.0, 0.0, 1.0]))  # 17 degrees down
    assert convention_floor(R[None], np.array([[5.0, 0.0, 2.5]])) is not None
