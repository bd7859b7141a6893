"""`rmpl convert-calib`: converts between formats; bad input exits 2 and writes nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.cli import main
from rmpl.geometry.camera import Camera, Rig, rodrigues
from rmpl.io.calibration import load_rig, save_rig


def _rig() -> Rig:
    K = np.array([[900.0, 0.0, 640.0], [0.0, 905.0, 360.0], [0.0, 0.0, 1.0]])
    return Rig(
        (
            Camera(
                K,
                rodrigues(np.array([0.1, -0.2, 0.3])),
                [0.2, 0.1, 4.0],
                [-0.1, 0.01, 0.001, 0.0, 0.0],
                (1280, 720),
                "left",
            ),
            Camera(
                K,
                rodrigues(np.array([-0.3, 0.5, 0.1])),
                [-0.4, 0.0, 3.5],
                np.zeros(5),
                (1280, 720),
                "right",
            ),
        )
    )


def test_convert_anipose_to_easymocap_and_back(tmp_path):
    rig = _rig()
    save_rig(rig, tmp_path / "in.toml", "anipose")
    assert main(["convert-calib", str(tmp_path / "in.toml"), str(tmp_path / "cams")]) == 0
    assert (tmp_path / "cams" / "intri.yml").is_file()
    assert (tmp_path / "cams" / "extri.yml").is_file()
    args = ["convert-calib", str(tmp_path / "cams"), str(tmp_path / "out.toml"), "--to", "anipose"]
    assert main(args) == 0
    back = load_rig(tmp_path / "out.toml", "anipose")
    assert back.names == rig.names
    np.testing.assert_allclose(back.K, rig.K)
    np.testing.assert_allclose(back.R, rig.R, atol=1e-12)
    np.testing.assert_allclose(back.t, rig.t, atol=1e-12)
    np.testing.assert_allclose(back.dist, rig.dist)


def test_units_options(tmp_path):
    save_rig(_rig(), tmp_path / "in.toml", "anipose")
    args = [
        "convert-calib",
        str(tmp_path / "in.toml"),
        str(tmp_path / "out.json"),
        "--in-units",
        "mm",
        "--to",
        "panoptic",
        "--out-units",
        "m",
    ]
    assert main(args) == 0
    cams = json.loads((tmp_path / "out.json").read_text())["cameras"]
    np.testing.assert_allclose(np.ravel(cams[0]["t"]), _rig().t[0] / 1000)


@pytest.mark.shared
def test_convert_real_shelf_calibration(shared_data, tmp_path):
    src = shared_data / "fixtures" / "shelf" / "calibration_shelf.json"
    out = tmp_path / "shelf.toml"
    assert main(["convert-calib", str(src), str(out)]) == 0
    np.testing.assert_allclose(load_rig(out).centers, load_rig(src).centers)


@pytest.mark.parametrize(
    "content",
    [
        "",
        '{"0": {"K": [1, 0, 0], "RT": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 3]}}',
        '{"cameras": [{"name": "a", "K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}]}',
    ],
)
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, content):
    src = tmp_path / "calibration.json"
    src.write_text(content)
    out = tmp_path / "out" / "calib.toml"
    assert main(["convert-calib", str(src), str(out)]) == 2
    err = capsys.readouterr().err
    assert str(src) in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["calibration.json"]


def test_refused_output_writes_nothing(tmp_path, capsys):
    save_rig(_rig(), tmp_path / "in.toml")
    out = tmp_path / "shelf.json"
    assert main(["convert-calib", str(tmp_path / "in.toml"), str(out), "--to", "shelf4d"]) == 2
    assert "dist" in capsys.readouterr().err
    assert not out.exists()


def test_unknown_format_name_is_a_usage_error(tmp_path):
    with pytest.raises(SystemExit) as err:
        main(["convert-calib", "a.json", str(tmp_path / "b.toml"), "--to", "colmap"])
    assert err.value.code == 2
