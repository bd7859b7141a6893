"""The HTML viewer: a self-contained page, its embedded data, and a real headless render."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.poses import Poses3D
from rmpl.skeleton import COCO17, H36M17
from rmpl.viz.viewer import UP_AXES, guess_up, view_rotation, write_viewer

K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])


def _rig(up=(0.0, 0.0, 1.0)) -> Rig:
    cams = []
    for i, eye in enumerate([(4.0, 0.0, 2.0), (0.0, 4.0, 2.5), (-4.0, -1.0, 1.5)]):
        R, t = look_at(np.array(eye), np.array([0.0, 0.0, 1.0]), np.array(up))
        cams.append(Camera(K, R, t, size=(640, 480), name=f"cam{i}"))
    return Rig(tuple(cams))


def _walkers(T: int = 12, P: int = 2) -> np.ndarray:
    """COCO-17 people standing on z = 0 (Z-up world) and walking along x, (T, P, 17, 3)."""
    rng = np.random.default_rng(0)
    heights = np.array(
        [
            1.6,
            1.65,
            1.65,
            1.6,
            1.6,
            1.45,
            1.45,
            1.15,
            1.15,
            0.9,
            0.9,
            0.95,
            0.95,
            0.5,
            0.5,
            0.08,
            0.08,
        ]
    )  # COCO-17 order, nose .. ankles
    body = np.column_stack([rng.uniform(-0.2, 0.2, 17), rng.uniform(-0.1, 0.1, 17), heights])
    t = np.arange(T)[:, None, None, None]
    offset = np.array([[0.0, 0.0, 0.0], [0.5, 1.0, 0.0], [-1.0, 0.5, 0.0]])[:P]
    return body + offset[None, :, None] + t * np.array([0.04, 0.0, 0.0])


def _embedded(page: str, element_id: str):
    m = re.search(rf'<script type="application/json" id="{element_id}">(.*?)</script>', page, re.S)
    assert m, element_id
    return json.loads(m.group(1))


def test_page_is_self_contained_and_carries_the_poses(tmp_path):
    pts = _walkers()
    pts[3, 1, 9] = np.nan
    out = write_viewer(pts, tmp_path / "view.html", skeleton="coco17", cameras=_rig(), fps=25)
    page = out.read_text(encoding="utf-8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["view.html"]  # no temporary left
    tags = re.findall(r"<(script|link|img|iframe)\b([^>]*)>", page)
    assert tags and all("src=" not in attrs and "href=" not in attrs for _, attrs in tags)
    assert page.count("</script>") == 3  # the two JSON blocks and the app: nothing broke out

    three = _embedded(page, "three-source")
    assert "SPDX-License-Identifier: MIT" in three and 'const t="170"' in three
    data = _embedded(page, "rmpl-data")
    assert data["up"] == "+z" and data["numFrames"] == 12 and data["numPeople"] == 2
    assert data["fps"] == 25 and data["fpsKnown"]
    assert data["bones"] == [list(b) for b in COCO17.bones]
    sides = dict(zip(map(tuple, data["bones"]), data["sides"], strict=True))
    assert sides[(COCO17.index("left_knee"), COCO17.index("left_hip"))] == "L"
    assert sides[(COCO17.index("right_elbow"), COCO17.index("right_wrist"))] == "R"
    assert sides[(COCO17.index("left_hip"), COCO17.index("right_hip"))] == "C"
    got = np.array([np.nan if v is None else v for v in data["points"]]).reshape(pts.shape)
    np.testing.assert_allclose(got, pts @ view_rotation("+z").T, atol=5e-4)  # 1 mm rounding
    missing = np.zeros(pts.shape[:-1], bool)
    missing[3, 1, 9] = True
    assert np.isnan(got[missing]).all() and np.isfinite(got[~missing]).all()
    assert [c["name"] for c in data["cameras"]] == ["cam0", "cam1", "cam2"]
    assert abs(data["floor"] - 0.08) < 0.01  # the lowest joints (ankles), viewer +Y up


def test_frusta_corners_project_to_the_image_corners(tmp_path):
    rig = _rig()
    data = _embedded(
        write_viewer(_walkers(), tmp_path / "v.html", "coco17", rig).read_text(), "rmpl-data"
    )
    back = view_rotation(data["up"])  # viewer -> world is its transpose
    for cam, drawn in zip(rig, data["cameras"], strict=True):
        corners = np.array(drawn["corners"]) @ back
        np.testing.assert_allclose(
            cam.project(corners), [[0, 0], [640, 0], [640, 480], [0, 480]], atol=1e-6
        )
        np.testing.assert_allclose(np.array(drawn["center"]) @ back, cam.center, atol=1e-9)
        depth = (cam.R @ corners.T + cam.t[:, None])[2]
        assert np.allclose(depth, depth[0]) and 0.1 < depth[0] <= 1.0


@pytest.mark.parametrize("up", sorted(UP_AXES))
def test_view_rotations_are_proper_and_put_up_on_y(up):
    R = view_rotation(up)
    axis = np.zeros(3)
    axis["xyz".index(up[1])] = 1.0 if up[0] == "+" else -1.0
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0)
    np.testing.assert_allclose(R @ axis, [0, 1, 0], atol=1e-12)


def test_guess_up_from_bodies_then_cameras_then_default():
    pts = _walkers()
    assert guess_up(pts, COCO17.joints) == "+z"
    y_down = pts @ np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]).T  # (x, y, z) -> (x, -z, y)
    assert guess_up(y_down, COCO17.joints) == "-y"
    assert guess_up(pts, None, _rig(up=(0.0, 1.0, 0.0))) == "+y"  # no names: cameras
    assert guess_up(np.full((2, 1, 17, 3), np.nan), COCO17.joints) == "+z"


def test_poses3d_gives_skeleton_fps_frames_and_ids(tmp_path):
    pts = _walkers(T=5, P=2)
    poses = Poses3D(
        points=pts,
        skeleton="coco17",
        fps=50.0,
        frames=np.arange(100, 105),
        person_ids=np.array([7, 3]),
    )
    data = _embedded(
        write_viewer(poses, tmp_path / "p.html", title="My <trial>").read_text(), "rmpl-data"
    )
    assert data["personIds"] == [7, 3] and data["frames"] == [100, 101, 102, 103, 104]
    assert data["fps"] == 50.0 and data["title"] == "My <trial>"
    assert "<title>My &lt;trial&gt;</title>" in (tmp_path / "p.html").read_text()


def test_plain_bones_and_a_single_person(tmp_path):
    pts = _walkers(P=1)[:, 0, :5]  # (T, 5, 3): one person, 5 joints, no skeleton name
    data = _embedded(
        write_viewer(pts, tmp_path / "b.html", [(0, 1), (1, 2), (3, 4)], up="+z").read_text(),
        "rmpl-data",
    )
    assert data["numPeople"] == 1 and data["sides"] == ["C", "C", "C"]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"poses": np.zeros((4, 2, 17, 2))}, "poses"),
        ({"skeleton": None}, "skeleton"),  # 17 joints: coco17 or h36m17, ambiguous
        ({"skeleton": "shelf14"}, "skeleton"),
        ({"skeleton": [(0, 17)]}, "skeleton"),
        ({"skeleton": "nope"}, "skeleton"),
        ({"up": "up"}, "up"),
        ({"fps": -1.0}, "fps"),
        ({"fps": "fast"}, "fps"),
        ({"cameras": "cam.toml"}, "cameras"),
    ],
)
def test_bad_input_names_the_field(tmp_path, kwargs, field):
    args = {"poses": _walkers(T=3), "skeleton": "coco17", **kwargs}
    with pytest.raises(InputError) as e:
        write_viewer(path=tmp_path / "x.html", **args)
    assert e.value.field == field
    assert not list(tmp_path.iterdir())  # nothing written


# --------------------------------------------------------------------------- in a browser


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if found := shutil.which(name):
            return found
    return None


def _dump_dom(url: str) -> str:
    browser = _chromium()
    if browser is None:
        pytest.skip("no chromium on PATH (Debian: apt-get install chromium)")
    with tempfile.TemporaryDirectory() as profile:
        done = subprocess.run(
            [
                browser,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-quic",
                "--disable-sync",
                "--no-first-run",
                "--enable-unsafe-swiftshader",
                "--host-resolver-rules=MAP * ~NOTFOUND",
                f"--user-data-dir={profile}",
                "--virtual-time-budget=5000",
                "--dump-dom",
                url,
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def _body_attributes(dom: str) -> dict[str, str]:
    tag = re.search(r"<body([^>]*)>", dom)
    assert tag, dom[:500]
    return dict(re.findall(r'data-([\w-]+)="([^"]*)"', tag.group(1)))


def test_headless_chromium_builds_the_scene_offline(tmp_path):
    pts = _walkers(T=8, P=3)
    pts[5, 0, [9, 10]] = np.nan  # both wrists: the two forearms go
    pts[5, 2] = np.nan  # a person absent from the frame
    out = write_viewer(pts, tmp_path / "scene.html", skeleton=COCO17, cameras=_rig(), fps=30)
    attrs = _body_attributes(_dump_dom(out.resolve().as_uri() + "?frame=5"))
    assert "error" not in attrs, attrs.get("error")
    assert attrs["loaded"] == "1"
    assert (attrs["frames"], attrs["people"], attrs["cameras"]) == ("8", "3", "3")
    assert attrs["bones"] == str(len(COCO17.bones)) and attrs["frame"] == "5"
    present = ~np.isnan(pts[5, :, :, 0])  # (P, J)
    want = sum(int(present[p, a] and present[p, b]) for p in range(3) for a, b in COCO17.bones)
    assert want == 2 * len(COCO17.bones) - 2
    assert attrs["visible-bones"] == str(want)
    if attrs.get("webgl") == "1":
        assert int(attrs["rendered"]) >= 1


def test_headless_chromium_with_h36m_and_no_cameras(tmp_path):
    pts = np.full((3, 1, 17, 3), np.nan)
    pts[:, 0] = np.random.default_rng(1).normal(0, 0.3, (17, 3)) + [0, 0, 1]
    out = write_viewer(pts, tmp_path / "h36m.html", skeleton=H36M17)
    attrs = _body_attributes(_dump_dom(out.resolve().as_uri()))
    assert "error" not in attrs, attrs.get("error")
    assert attrs["loaded"] == "1" and attrs["cameras"] == "0" and attrs["people"] == "1"
    assert attrs["visible-bones"] == str(len(H36M17.bones))
