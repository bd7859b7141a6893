"""Bad-input corpus for calibration files: every case is one InputError naming file and field.

Each case builds a broken calibration in a temporary folder (from a good rig written by
rmpl, then damaged the way real files are: a key missing, NaN, a matrix that is not a
rotation, a singular K, a truncated or binary file, a camera given twice, wrong types, ...)
and checks that :func:`rmpl.io.calibration.load_rig` refuses it with a single
:class:`rmpl.errors.InputError` whose message names the file and the field. A few cases go
through ``rmpl convert-calib`` in a subprocess: one line on stderr, a non-zero exit, and
no output written.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig
from rmpl.io.calibration import load_rig, save_rig

K = [[800.0, 0.0, 320.0], [0.0, 810.0, 240.0], [0.0, 0.0, 1.0]]
QUARTER_TURN_Z = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
NOT_A_ROTATION = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


def _rig() -> Rig:
    """Two cameras, "a" and "b", 3 m from the origin."""
    cams = (
        Camera(np.array(K), np.eye(3), [0.0, 0.0, 3.0], np.zeros(5), (640, 480), "a"),
        Camera(
            np.array(K), np.array(QUARTER_TURN_Z), [0.5, 0.0, 3.0], np.zeros(5), (640, 480), "b"
        ),
    )
    return Rig(cams)


@dataclass(frozen=True)
class Case:
    """A broken calibration: ``make(folder)`` writes it and returns the path to load.

    ``field`` is the field the error must name (None: the file as a whole, e.g. not JSON),
    ``words`` what else the message must say, ``options`` what to pass to load_rig.
    """

    make: Callable[[Path], Path]
    field: str | None
    words: tuple[str, ...] = ()
    options: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------------------
# Builders


def _json(fmt: str, name: str, change: Callable[[dict], object]) -> Callable[[Path], Path]:
    """A good ``fmt`` file written by rmpl, parsed, changed by ``change``, written back."""

    def make(folder: Path) -> Path:
        path = folder / name
        save_rig(_rig(), path, fmt)
        doc = json.loads(path.read_text())
        change(doc)
        path.write_text(json.dumps(doc))
        return path

    return make


def _text(fmt: str, name: str, old: str, new: str) -> Callable[[Path], Path]:
    """A good ``fmt`` file written by rmpl with the first ``old`` replaced by ``new``."""

    def make(folder: Path) -> Path:
        path = folder / name
        save_rig(_rig(), path, fmt)
        text = path.read_text()
        assert old in text, f"the corpus case no longer matches the {fmt} writer"
        path.write_text(text.replace(old, new, 1))
        return path

    return make


def _easymocap(which: str, old: str, new: str) -> Callable[[Path], Path]:
    """An EasyMocap folder written by rmpl with ``which`` (intri/extri) damaged."""

    def make(folder: Path) -> Path:
        save_rig(_rig(), folder, "easymocap")
        path = folder / f"{which}.yml"
        text = path.read_text()
        assert old in text, "the corpus case no longer matches the easymocap writer"
        path.write_text(text.replace(old, new, 1))
        return path

    return make


def _raw(name: str, content: str | bytes) -> Callable[[Path], Path]:
    def make(folder: Path) -> Path:
        path = folder / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
        return path

    return make


def _truncated(fmt: str, name: str) -> Callable[[Path], Path]:
    """A good file cut in the middle, as a full disk or an interrupted copy leaves it."""

    def make(folder: Path) -> Path:
        path = folder / name
        save_rig(_rig(), path, fmt)
        text = path.read_text()
        path.write_text(text[: len(text) // 2])
        return path

    return make


def _repeated_camera(fmt: str, name: str) -> Callable[[Path], Path]:
    """A JSON file whose camera "b" is renamed "a": the key given twice."""

    def make(folder: Path) -> Path:
        path = folder / name
        save_rig(_rig(), path, fmt)
        text = path.read_text()
        assert text.count('"b"') == 1
        path.write_text(text.replace('"b"', '"a"'))
        return path

    return make


def _h36m(change: Callable[[dict], object] = lambda d: None, text: str | None = None):
    """A one-camera Human3.6M ``camera-parameters.json``, changed by ``change``."""

    def make(folder: Path) -> Path:
        intr = {"calibration_matrix": K, "distortion": [0.0] * 5}
        extr = {"R": np.eye(3).tolist(), "t": [[0.0], [0.0], [5000.0]]}
        doc = {"intrinsics": {"c1": intr}, "extrinsics": {"S1": {"c1": extr}}}
        change(doc)
        path = folder / "camera-parameters.json"
        path.write_text(text if text is not None else json.dumps(doc))
        return path

    return make


_QCA_CAMERA = (
    '<camera active="1" serial="{serial}" model="none" video_resolution="1080p">'
    '<fov_video left="0" top="0" right="1919" bottom="1079"/>'
    '<transform x="0" y="-3000" z="1000" r11="1" r12="0" r13="0" r21="0" r22="0" r23="1" '
    'r31="0" r32="-1" r33="0"/>'
    '<intrinsic focalLengthU="64000" focalLengthV="64000" centerPointU="61440" '
    'centerPointV="34560" radialDistortion1="0" radialDistortion2="0" '
    'tangentalDistortion1="0" tangentalDistortion2="0"/>'
    "</camera>"
)


def _qualisys(old: str = "", new: str = "") -> Callable[[Path], Path]:
    """A one-camera Qualisys ``.qca.txt`` with ``old`` replaced by ``new``."""

    def make(folder: Path) -> Path:
        text = f"<calibration><cameras>{_QCA_CAMERA.format(serial=7)}</cameras></calibration>"
        assert old in text
        path = folder / "Calib.qca.txt"
        path.write_text(text.replace(old, new, 1) if old else text)
        return path

    return make


def _pickle(doc: object) -> Callable[[Path], Path]:
    return _raw("cameras.pkl", pickle.dumps(doc))


def _folder(name: str) -> Callable[[Path], Path]:
    def make(folder: Path) -> Path:
        (folder / name).mkdir()
        return folder / name

    return make


def _set(camera: int, **values) -> Callable[[dict], None]:
    return lambda d: d["cameras"][camera].update(values)


def _pop(camera: int, key: str) -> Callable[[dict], None]:
    return lambda d: d["cameras"][camera].pop(key)


# ---------------------------------------------------------------------------------------
# The corpus

CASES = {
    # rmpl TOML / JSON
    "rmpl-json missing K": Case(_json("rmpl-json", "c.json", _pop(0, "K")), "cameras[0].K"),
    "rmpl-json missing cameras": Case(
        _json("rmpl-json", "c.json", lambda d: d.pop("cameras")), "cameras", ("missing",)
    ),
    "rmpl-json NaN in t": Case(
        _json("rmpl-json", "c.json", _set(0, t=[0.0, float("nan"), 3.0])),
        "cameras[0].t",
        ("finite",),
    ),
    "rmpl-json R not a rotation": Case(
        _json("rmpl-json", "c.json", _set(1, R=NOT_A_ROTATION)), "cameras[1].R", ("rotation",)
    ),
    "rmpl-json R a reflection": Case(
        _json("rmpl-json", "c.json", _set(0, R=np.diag([1.0, 1.0, -1.0]).tolist())),
        "cameras[0].R",
        ("det R",),
    ),
    "rmpl-json singular K": Case(
        _json("rmpl-json", "c.json", _set(0, K=[[0.0, 0, 0], [0, 0, 0], [0, 0, 0]])),
        "cameras[0].K",
    ),
    "rmpl-json negative focal": Case(
        _json("rmpl-json", "c.json", _set(0, K=[[-800.0, 0, 320], [0, 810, 240], [0, 0, 1]])),
        "cameras[0].K",
        ("positive focal",),
    ),
    "rmpl-json K bottom row": Case(
        _json("rmpl-json", "c.json", _set(1, K=[[800.0, 0, 320], [0, 810, 240], [1, 0, 1]])),
        "cameras[1].K",
    ),
    "rmpl-json K of strings": Case(
        _json("rmpl-json", "c.json", _set(0, K="identity")), "cameras[0].K", ("3x3",)
    ),
    "rmpl-json t of 2 numbers": Case(
        _json("rmpl-json", "c.json", _set(0, t=[0.0, 3.0])), "cameras[0].t", ("3 numbers",)
    ),
    "rmpl-json 3 distortion coefficients": Case(
        _json("rmpl-json", "c.json", _set(0, dist=[0.1, 0.0, 0.0])), "cameras[0].dist"
    ),
    "rmpl-json 8 distortion coefficients": Case(
        _json("rmpl-json", "c.json", _set(1, dist=[0.0] * 8)), "cameras[1].dist"
    ),
    "rmpl-json fractional image size": Case(
        _json("rmpl-json", "c.json", _set(0, size=[640.5, 480])), "cameras[0].size"
    ),
    "rmpl-json zero image size": Case(
        _json("rmpl-json", "c.json", _set(0, size=[0, 480])), "cameras[0].size"
    ),
    "rmpl-json zero cameras": Case(
        _json("rmpl-json", "c.json", lambda d: d.update(cameras=[])), "cameras", ("at least one",)
    ),
    "rmpl-json camera not a table": Case(
        _json("rmpl-json", "c.json", lambda d: d["cameras"].__setitem__(0, [1, 2])), "cameras[0]"
    ),
    "rmpl-json repeated camera name": Case(
        _json("rmpl-json", "c.json", _set(1, name="a")), "cameras", ("unique",)
    ),
    "rmpl-json repeated key": Case(
        _text("rmpl-json", "c.json", '"name": "b"', '"name": "b", "name": "c"'), "name"
    ),
    "rmpl-json unknown units": Case(
        _json("rmpl-json", "c.json", lambda d: d["metadata"].update(units="furlong")),
        "metadata.units",
    ),
    "rmpl-json truncated": Case(_truncated("rmpl-json", "c.json"), None, ("valid JSON",)),
    "rmpl-toml truncated": Case(_truncated("rmpl-toml", "c.toml"), None, ("valid TOML",)),
    "rmpl-toml nan in t": Case(
        _text("rmpl-toml", "c.toml", "t = [0.0, 0.0, 3.0]", "t = [0.0, nan, 3.0]"),
        "cameras[0].t",
    ),
    "rmpl-toml inf in K": Case(
        _text("rmpl-toml", "c.toml", "[0.0, 0.0, 1.0]]", "[0.0, 0.0, inf]]"), "cameras[0].K"
    ),
    "rmpl-toml R of booleans": Case(
        _text("rmpl-toml", "c.toml", "R = [[1.0, 0.0, 0.0]", "R = [[true, false, false]"),
        "cameras[0].R",
    ),
    # anipose / Pose2Sim TOML
    "anipose missing rotation": Case(
        _text("anipose", "c.toml", "rotation = [0.0, 0.0, 0.0]\n", ""), "a.rotation"
    ),
    "anipose rotation of 2 numbers": Case(
        _text("anipose", "c.toml", "rotation = [0.0, 0.0, 0.0]", "rotation = [0.0, 0.0]"),
        "a.rotation",
    ),
    "anipose translation a string": Case(
        _text("anipose", "c.toml", "translation = [0.0, 0.0, 3.0]", 'translation = "3 m"'),
        "a.translation",
    ),
    "anipose negative image size": Case(
        _text("anipose", "c.toml", "size = [640, 480]", "size = [-640, 480]"), "a.size"
    ),
    "anipose fisheye": Case(
        _text("anipose", "c.toml", "fisheye = false", "fisheye = true"), "a.fisheye"
    ),
    "anipose camera not a table": Case(
        _raw("c.toml", 'cam_1 = 3\n[metadata]\nunits = "m"\n'), "cam_1"
    ),
    # CMU Panoptic
    "panoptic missing distCoef": Case(
        _json("panoptic", "calibration_x.json", _pop(0, "distCoef")), "cameras[0].distCoef"
    ),
    "panoptic NaN in R": Case(
        _json("panoptic", "calibration_x.json", _set(1, R=[[float("nan")] * 3] * 3)),
        "cameras[1].R",
    ),
    "panoptic no camera of the type": Case(
        _json("panoptic", "calibration_x.json", lambda d: None),
        "cameras[].type",
        options={"camera_type": "vga"},
    ),
    # Shelf / Campus
    "shelf4d repeated camera key": Case(
        _repeated_camera("shelf4d", "calibration.json"), "a", ("repeated",)
    ),
    "shelf4d RT of 11 numbers": Case(
        _json("shelf4d", "calibration.json", lambda d: d["a"].update(RT=d["a"]["RT"][:11])),
        "a.RT",
    ),
    "shelf4d RT not a rotation": Case(
        _json("shelf4d", "calibration.json", lambda d: d["b"]["RT"].__setitem__(0, 3.0)), "b.RT"
    ),
    "shelf4d K a string": Case(
        _json("shelf4d", "calibration.json", lambda d: d["a"].update(K="800 0 320")), "a.K"
    ),
    "voxelpose repeated camera key": Case(
        _repeated_camera("voxelpose", "calibration_shelf.json"), "a", ("repeated",)
    ),
    "voxelpose negative fy": Case(
        _json("voxelpose", "calibration_shelf.json", lambda d: d["a"].update(fy=-810.0)),
        "a.fx/fy",
    ),
    "voxelpose missing p": Case(
        _json("voxelpose", "calibration_shelf.json", lambda d: d["b"].pop("p")), "b.p"
    ),
    "voxelpose T a table": Case(
        _json("voxelpose", "calibration_shelf.json", lambda d: d["a"].update(T={"x": 1})), "a.T"
    ),
    # Human3.6M
    "h36m repeated camera id": Case(
        _h36m(text='{"intrinsics": {"c1": {}, "c1": {}}, "extrinsics": {"S1": {"c1": {}}}}'),
        "c1",
        ("repeated",),
    ),
    "h36m unknown subject": Case(_h36m(), "extrinsics.S9", options={"subject": "S9"}),
    "h36m t in a string": Case(
        _h36m(lambda d: d["extrinsics"]["S1"]["c1"].update(t="5 m")), "extrinsics.S1.c1.t"
    ),
    "h36m-pkl not a dict": Case(_pickle([1, 2, 3]), None, ("dict",)),
    "h36m-pkl camera without f": Case(
        _pickle({("S1", "1"): {"R": np.eye(3), "T": np.zeros(3)}}), "('S1', '1').f"
    ),
    # EasyMocap
    "easymocap missing K_b": Case(
        _easymocap("intri", "K_b: !!opencv-matrix", "Kb: !!opencv-matrix"), "K_b"
    ),
    "easymocap NaN in K": Case(_easymocap("intri", "data: [ 800.0", "data: [ .nan"), "K_a"),
    "easymocap rows do not match data": Case(
        _easymocap("intri", "K_b: !!opencv-matrix\n   rows: 3", "K_b: !!opencv-matrix\n   rows: 2"),
        "K_b",
    ),
    "easymocap missing T_a": Case(_easymocap("extri", "T_a:", "U_a:"), "T_a"),
    "easymocap no YAML header": Case(_easymocap("intri", "%YAML:1.0\n", ""), None, ("%YAML",)),
    # Qualisys
    "qualisys missing intrinsic": Case(
        _qualisys("<intrinsic ", "<other "), "camera[7].intrinsic", ("element",)
    ),
    "qualisys focal not a number": Case(
        _qualisys('focalLengthU="64000"', 'focalLengthU="wide"'),
        "camera[7].intrinsic.focalLengthU",
    ),
    "qualisys not a rotation": Case(
        _qualisys('r11="1"', 'r11="3"'), "camera[7].transform", ("rotation",)
    ),
    "qualisys bad resolution": Case(
        _qualisys('video_resolution="1080p"', 'video_resolution="HD"'),
        "camera[7].video_resolution",
    ),
    "qualisys truncated XML": Case(_qualisys("</calibration>", "</cameras>"), None, ("valid XML",)),
    # Files that are not calibrations at all
    "empty JSON file": Case(_raw("c.json", ""), None, ("empty",)),
    "empty TOML file": Case(_raw("c.toml", "\n\n  \n"), None, ("empty",)),
    "empty pickle": Case(_raw("cameras.pkl", b""), None, ("empty",)),
    "binary JSON file": Case(_raw("c.json", bytes(range(256)) * 4), None, ("UTF-8",)),
    "binary YAML file": Case(_raw("intri.yml", b"\x89PNG\r\n\x1a\n\xff\xfe\x00"), None, ("UTF-8",)),
    "JSON of an unknown layout": Case(_raw("c.json", '{"hello": [1, 2]}'), "format"),
    "JSON top-level list": Case(_raw("c.json", "[1, 2, 3]"), "format"),
    "unknown extension": Case(_raw("calib.xyz", "cameras"), "format"),
    "missing file": Case(lambda folder: folder / "nope.json", None, ("no such file",)),
    "a folder given as a JSON file": Case(
        _folder("calib.json"), None, ("folder",), {"format": "rmpl-json"}
    ),
    "a folder without intri.yml": Case(_folder("calib"), None, ("intri.yml",)),
    "unknown format name": Case(_raw("c.json", "{}"), "format", options={"format": "colmap"}),
}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_calibration_is_one_input_error(tmp_path, name):
    case = CASES[name]
    path = case.make(tmp_path)
    with pytest.raises(InputError) as err:
        load_rig(path, **case.options)
    message = str(err.value)
    assert str(path) in message
    assert err.value.field == case.field
    if case.field is not None:
        assert repr(case.field) in message
    for word in case.words:
        assert word in message
    assert "\n" not in message


def test_the_corpus_is_large_enough():
    assert len(CASES) >= 25
    formats = ("rmpl-json", "rmpl-toml", "anipose", "panoptic", "shelf4d", "voxelpose")
    formats += ("h36m", "easymocap", "qualisys")
    assert all(any(n.startswith(f) for n in CASES) for f in formats)


# ---------------------------------------------------------------------------------------
# Through the command line: one line on stderr, a non-zero exit, nothing written

CLI_CASES = [
    "rmpl-json truncated",
    "shelf4d repeated camera key",
    "binary JSON file",
    "rmpl-json singular K",
    "a folder without intri.yml",
]


_MAIN = "import sys; from rmpl.cli import main; sys.exit(main())"


def _convert(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run(
        [sys.executable, "-c", _MAIN, "convert-calib", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )


@pytest.mark.parametrize("name", CLI_CASES)
def test_convert_calib_refuses_bad_input_in_one_line(tmp_path, name):
    case = CASES[name]
    path = case.make(tmp_path)
    out = tmp_path / "out.toml"
    result = _convert(str(path), str(out))
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert str(path) in lines[0] and "Traceback" not in result.stderr
    if case.field is not None:
        assert repr(case.field) in lines[0]
    assert not out.exists()


def test_convert_calib_onto_a_folder_leaves_the_old_pair(tmp_path):
    good = tmp_path / "good.json"
    save_rig(_rig(), good)
    target = tmp_path / "em"
    save_rig(_rig(), target, "easymocap")
    extri = (target / "extri.yml").read_text()
    (target / "intri.yml").unlink()
    (target / "intri.yml").mkdir()
    result = _convert(str(good), str(target), "--to", "easymocap", "--out-units", "mm")
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(target / "intri.yml") in lines[0], result.stderr
    assert (target / "extri.yml").read_text() == extri
