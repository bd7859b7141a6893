"""The 3D commands end to end on tiny scenes built here, and their bad-input behaviour."""

import json
from pathlib import Path

import numpy as np
import pytest
import torch

import rmpl
from rmpl.cli import main
from rmpl.geometry.camera import Camera, Rig, look_at
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.io.poses import load_poses
from rmpl.model.lifter import PRESETS, RMPL
from rmpl.training.loop import save_checkpoint


def make_scene(tmp_path, views=3, frames=6, seed=0):
    rng = np.random.default_rng(seed)
    K = np.array([[900.0, 0, 480], [0, 900, 360], [0, 0, 1]])
    cams = []
    for v in range(views):
        a = 2 * np.pi * v / views
        R, t = look_at(np.array([4 * np.cos(a), 4 * np.sin(a), 2.0]), np.array([0.0, 0, 1]))
        cams.append(Camera(K, R, t, size=(960, 720), name=f"cam{v}"))
    rig = Rig(tuple(cams))
    X = rng.uniform(-0.4, 0.4, (frames, 17, 3)) + [0, 0, 1]
    kp = rig.project(X)  # (T, V, J, 2)
    sc = np.full(kp.shape[:-1], 0.9)
    save_rig(rig, tmp_path / "calib.toml")
    save_keypoints(
        Keypoints2D(kp[:, :, None], sc[:, :, None], "coco17", rig.names, np.arange(frames), 30.0),
        tmp_path / "kp.json",
    )
    return X


@pytest.fixture
def tiny_model(tmp_path):
    torch.manual_seed(0)
    save_checkpoint(RMPL(PRESETS["tiny"]), tmp_path / "model")
    return str(tmp_path / "model")


@pytest.mark.parametrize("suffix", [".npz", ".json", ".trc", ".c3d"])
def test_triangulate_writes_every_format(tmp_path, suffix):
    X = make_scene(tmp_path)
    out = tmp_path / f"out{suffix}"
    args = [
        "triangulate",
        "--calib",
        str(tmp_path / "calib.toml"),
        "--keypoints",
        str(tmp_path / "kp.json"),
        "--out",
        str(out),
    ]
    assert main(args) == 0
    assert out.is_file()
    if suffix in (".npz", ".json", ".trc"):
        got = load_poses(out).points[:, 0]
        assert np.allclose(got, X, atol=1e-4)


def test_triangulate_robust(tmp_path):
    X = make_scene(tmp_path, views=4)
    out = tmp_path / "out.npz"
    assert (
        main(
            [
                "triangulate",
                "--robust",
                "--calib",
                str(tmp_path / "calib.toml"),
                "--keypoints",
                str(tmp_path / "kp.json"),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert np.allclose(load_poses(out).points[:, 0], X, atol=1e-4)


def test_lift_with_a_checkpoint(tmp_path, tiny_model):
    make_scene(tmp_path)
    out = tmp_path / "lifted.json"
    assert (
        main(
            [
                "lift",
                "--model",
                tiny_model,
                "--calib",
                str(tmp_path / "calib.toml"),
                "--keypoints",
                str(tmp_path / "kp.json"),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    doc = json.loads(out.read_text())
    poses = load_poses(out)
    assert poses.points.shape == (6, 1, 17, 3)
    assert np.isfinite(poses.points).all()
    assert (poses.num_views == 3).all()
    assert doc  # a JSON document, not an empty file


def test_views_not_matching_calibration_fail_cleanly(tmp_path, tiny_model, capsys):
    make_scene(tmp_path, views=3)
    other = tmp_path / "other"
    other.mkdir()
    make_scene(other, views=2)
    out = tmp_path / "x.npz"
    for cmd in (["lift", "--model", tiny_model], ["triangulate"]):
        code = main(
            [
                *cmd,
                "--calib",
                str(other / "calib.toml"),
                "--keypoints",
                str(tmp_path / "kp.json"),
                "--out",
                str(out),
            ]
        )
        assert code == 2
        err = capsys.readouterr().err
        assert "views" in err and "calib.toml" in err
        assert not out.exists()


def test_all_zero_confidence_is_an_error(tmp_path, tiny_model, capsys):
    make_scene(tmp_path)
    kp = json.loads((tmp_path / "kp.json").read_text())
    kp["scores"] = np.zeros(np.shape(kp["scores"])).tolist()
    kp["keypoints"] = np.full(np.shape(kp["keypoints"]), np.nan).tolist()
    (tmp_path / "kp.json").write_text(json.dumps(kp).replace("NaN", "null"))
    out = tmp_path / "x.npz"
    code = main(
        [
            "lift",
            "--model",
            tiny_model,
            "--calib",
            str(tmp_path / "calib.toml"),
            "--keypoints",
            str(tmp_path / "kp.json"),
            "--out",
            str(out),
        ]
    )
    assert code == 2
    assert "scores" in capsys.readouterr().err
    assert not out.exists()


def test_bad_output_suffix(tmp_path, capsys):
    make_scene(tmp_path)
    code = main(
        [
            "triangulate",
            "--calib",
            str(tmp_path / "calib.toml"),
            "--keypoints",
            str(tmp_path / "kp.json"),
            "--out",
            str(tmp_path / "x.xlsx"),
        ]
    )
    assert code == 2
    assert ".trc" in capsys.readouterr().err


def test_missing_calibration_file(tmp_path, capsys):
    make_scene(tmp_path)
    code = main(
        [
            "triangulate",
            "--calib",
            str(tmp_path / "nope.toml"),
            "--keypoints",
            str(tmp_path / "kp.json"),
            "--out",
            str(tmp_path / "x.npz"),
        ]
    )
    assert code == 2
    assert "nope.toml" in capsys.readouterr().err


def test_unknown_model_name(tmp_path, capsys):
    make_scene(tmp_path)
    code = main(
        [
            "lift",
            "--model",
            "no-such-model",
            "--calib",
            str(tmp_path / "calib.toml"),
            "--keypoints",
            str(tmp_path / "kp.json"),
            "--out",
            str(tmp_path / "x.npz"),
        ]
    )
    assert code == 2
    assert "no-such-model" in capsys.readouterr().err


# --------------------------------------------------------------------------- filesystem errors


def _command(name: str, tmp_path, out: str) -> list[str]:
    make_scene(tmp_path)
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    return {
        "triangulate": ["triangulate", *io, "--out", out],
        "lift": ["lift", *io, "--out", out, "--model", "default"],
        "run": ["run", *io, "--out", out, "--method", "triangulate", "--no-pictures"],
        "example": ["example", "--out", out],
    }[name]


def _one_line_error(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


@pytest.mark.parametrize("name", ["triangulate", "lift", "run", "example"])
def test_output_under_a_regular_file(tmp_path, capsys, name):
    (tmp_path / "blocker").write_text("a file")
    out = tmp_path / "blocker" / ("poses.json" if name in ("triangulate", "lift") else "res")
    assert main(_command(name, tmp_path, str(out))) == 2
    _one_line_error(capsys, str(tmp_path / "blocker"), "expected")


@pytest.mark.parametrize("name", ["triangulate", "lift"])
def test_output_file_that_is_a_directory(tmp_path, capsys, name):
    (tmp_path / "out.json").mkdir()
    assert main(_command(name, tmp_path, str(tmp_path / "out.json"))) == 2
    _one_line_error(capsys, "out.json", "expected an output file path")


@pytest.mark.parametrize("name", ["run", "example"])
def test_output_folder_that_is_a_regular_file(tmp_path, capsys, name):
    (tmp_path / "res").write_text("a file")
    assert main(_command(name, tmp_path, str(tmp_path / "res"))) == 2
    _one_line_error(capsys, "res", "expected an output folder")


@pytest.mark.parametrize("name", ["triangulate", "run"])
def test_unwritable_output_folder(tmp_path, capsys, monkeypatch, name):
    # The tests may run as root, who writes anywhere: the folder refuses writes instead.
    import rmpl.io.atomic as atomic

    def locked(path, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(path))

    out = str(tmp_path / ("o.json" if name == "triangulate" else "res"))
    args = _command(name, tmp_path, out)
    monkeypatch.setattr(atomic.Path, "touch", locked)
    assert main(args) == 2
    _one_line_error(capsys, "Permission denied", "expected a path you may read")


@pytest.mark.parametrize(
    "damage", ["garbage", "truncated", "wrong_tensors", "bad_config", "no_weights"]
)
def test_corrupt_model_checkpoint(tmp_path, capsys, tiny_model, damage):
    from pathlib import Path

    model = Path(tiny_model)
    weights = model / "model.safetensors"
    if damage == "garbage":
        weights.write_bytes(b"\x00not safetensors at all" * 10)
    elif damage == "truncated":
        weights.write_bytes(weights.read_bytes()[:1000])
    elif damage == "wrong_tensors":
        torch.manual_seed(0)
        save_checkpoint(RMPL(PRESETS["small"]), tmp_path / "other")
        weights.write_bytes((tmp_path / "other" / "model.safetensors").read_bytes())
    elif damage == "bad_config":
        (model / "config.json").write_text("{not json")
    else:
        weights.unlink()
    args = _command("lift", tmp_path, str(tmp_path / "o.json"))
    args[args.index("--model") + 1] = tiny_model
    assert main(args) == 2
    name = "config.json" if damage == "bad_config" else "model.safetensors"
    _one_line_error(capsys, name, "expected")


# --------------------------------------------------------------------------- one camera


def _one_camera_walk(tmp_path, height=2.5, fps=30.0):
    """The shipped example's walk (ankles ~0.1 m above z = 0) seen by one camera, its 2D
    file stating ``fps``."""
    from pathlib import Path

    import rmpl

    X = np.load(Path(rmpl.__file__).parent / "examples" / "walk" / "ground_truth.npz")["points"]
    X = X[:, 0].astype(float)  # (60, 17, 3)
    K = np.array([[1000.0, 0, 640], [0, 1000, 360], [0, 0, 1]])
    R, t = look_at(np.array([5.0, 0.5, height]), np.array([0.0, 0, 1]))
    rig = Rig((Camera(K, R, t, size=(1280, 720), name="cam"),))
    kp = rig.project(X)  # (60, 1, 17, 2)
    sc = np.full(kp.shape[:-1], 0.9)
    save_rig(rig, tmp_path / "calib.toml")
    save_keypoints(
        Keypoints2D(kp[:, :, None], sc[:, :, None], "coco17", rig.names, np.arange(60), fps),
        tmp_path / "kp.json",
    )
    return X


def _root_error(poses, X) -> float:
    root = lambda x: x[..., [11, 12], :].mean(-2)  # noqa: E731
    return float(np.linalg.norm(root(poses.points[:, 0]) - root(X), axis=-1).mean())


def test_run_one_camera_end_to_end_with_the_floor(tmp_path, caplog):
    X = _one_camera_walk(tmp_path)
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    with caplog.at_level("INFO"):
        assert main(["run", *io, "--out", str(tmp_path / "f"), "--floor", "z=0",
                     "--no-pictures", "--formats", "npz,json"]) == 0  # fmt: skip
    text = caplog.text
    assert "one camera: depth along the rays comes from priors" in text
    assert "--floor z=0" in text and "depth uncertainty" in text
    poses = load_poses(tmp_path / "f" / "poses.npz")
    from rmpl import Lifter
    from rmpl.models import ONE_CAMERA

    J = Lifter.from_pretrained(ONE_CAMERA).num_joints  # rmpl run's one-camera model's joints
    assert poses.points.shape == (60, 1, J, 3) and np.isfinite(poses.points).all()
    u = poses.uncertainty
    assert u is not None and np.isfinite(u).all() and (u > 0).all()
    # The floor fixes where along the rays the walker is. The example's ankles rest 0.1 m
    # above z = 0 where 0.07 is assumed: the floor at z = 0.03 is the right one, z = 0 is
    # 3 cm off, and no floor leaves the size prior.
    errors = {"z=0": _root_error(poses, X)}
    for floor in ("z=0.03", "none"):
        out = tmp_path / floor
        with caplog.at_level("INFO"):
            assert main(["run", *io, "--out", str(out), "--floor", floor,
                         "--no-pictures", "--formats", "npz"]) == 0  # fmt: skip
        errors[floor] = _root_error(load_poses(out / "poses.npz"), X)
    assert "no floor" in caplog.text
    assert errors["z=0.03"] < errors["z=0"] < errors["none"]
    assert errors["z=0.03"] < 0.2


def test_lift_one_camera_uses_the_calibration_convention(tmp_path, caplog):
    X = _one_camera_walk(tmp_path)
    out = tmp_path / "lifted.npz"
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    with caplog.at_level("INFO"):
        assert main(["lift", *io, "--out", str(out)]) == 0
    assert "calibration convention: z up" in caplog.text
    given = tmp_path / "given.npz"
    assert main(["lift", *io, "--out", str(given), "--floor", "z=0"]) == 0
    assert np.array_equal(load_poses(out).points, load_poses(given).points)  # the same floor
    assert np.isfinite(load_poses(out).points).all() and X.shape == (60, 17, 3)


@pytest.mark.parametrize(
    "floor, words",
    [("z=3", ["--floor", "below the cameras"]), ("0,0,0,1", ["--floor", "plane"]),
     ("up", ["--floor", "AXIS=H"]), ("multi.npz", ["--floor", "existing poses file"])],
)  # fmt: skip
def test_run_one_camera_refuses_a_bad_floor(tmp_path, capsys, floor, words):
    _one_camera_walk(tmp_path)
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    out = tmp_path / "res"
    assert main(["run", *io, "--out", str(out), "--floor", floor, "--no-pictures"]) == 2
    _one_line_error(capsys, *words)
    assert not (out / "poses.npz").exists()


def test_floor_from_a_multi_view_result(tmp_path, caplog):
    X = _one_camera_walk(tmp_path)
    from rmpl.io.poses import Poses3D, save_poses

    wide = np.concatenate([X + [dx, dy, 0.0] for dx in (-1.5, 1.5) for dy in (-1.5, 1.5)])
    save_poses(Poses3D(wide[:, None]), tmp_path / "multi.npz")
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    with caplog.at_level("INFO"):
        assert main(["lift", *io, "--out", str(tmp_path / "o.npz"),
                     "--floor", str(tmp_path / "multi.npz")]) == 0  # fmt: skip
    assert "estimated from 240 ankle positions" in caplog.text


def test_floor_is_not_used_by_a_model_that_does_not_read_it(tmp_path, tiny_model, caplog):
    make_scene(tmp_path)
    io = ["--calib", str(tmp_path / "calib.toml"), "--keypoints", str(tmp_path / "kp.json")]
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    assert main(["lift", "--model", tiny_model, *io, "--out", str(a)]) == 0
    with caplog.at_level("WARNING"):
        assert main(["lift", "--model", tiny_model, *io, "--out", str(b), "--floor", "z=0"]) == 0
    assert caplog.text.count("the floor given is not used") == 1  # said once
    assert np.array_equal(load_poses(a).points, load_poses(b).points)


def test_multi_view_run_gives_floor26_the_floor(tmp_path, caplog):
    # The embedded 4-camera walk: by default the floor is fitted under the run's own
    # triangulated people and floor26 reads it; --floor none and a plane change the answer,
    # and report.json says which floor the lifter read.
    walk = Path(rmpl.__file__).parent / "examples" / "walk"
    io = ["--calib", str(walk / "calibration.toml"), "--keypoints", str(walk / "keypoints.json"),
          "--model", "floor26", "--no-pictures", "--formats", "npz"]  # fmt: skip
    floors, points = {}, {}
    for name, extra in (("estimate", []), ("none", ["--floor", "none"]),
                        ("plane", ["--floor", "z=0.2"])):  # fmt: skip
        out = tmp_path / name
        with caplog.at_level("INFO"):
            assert main(["run", *io, *extra, "--out", str(out)]) == 0
        floors[name] = json.loads((out / "report.json").read_text())["floor"]
        points[name] = load_poses(out / "poses.npz").points
    assert floors["none"] == {"given": False, "description": "none"}
    est = floors["estimate"]
    assert est["given"] and "triangulated from the run's 4 cameras" in est["source"]
    assert abs(est["height_m"]) < 0.1 and est["normal"][2] > 0.99  # the walk is on z = 0
    assert floors["plane"]["given"] and floors["plane"]["height_m"] == pytest.approx(0.2)
    assert "floor given to the lifter" in caplog.text
    for a, b in (("estimate", "none"), ("estimate", "plane")):
        assert not np.allclose(points[a], points[b], equal_nan=True), (a, b)
