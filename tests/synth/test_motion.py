import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rmpl.errors import InputError
from rmpl.skeleton import COCO17
from rmpl.synth.motion import (
    FACE_OFFSETS,
    FRAME_RATES,
    HIP_OFFSET,
    LENGTH_UNITS,
    Y_UP_TO_Z_UP,
    PoseSet,
    build_pose_cache,
    detect_length_unit,
    find_clips,
    floor_height,
    load_asf_amc,
    load_bvh,
    load_motion_dir,
    load_pose_set,
    mirror,
    read_asf,
    save_pose_set,
    to_coco17,
    usable_frames,
)

A = Y_UP_TO_Z_UP
CMU_UNIT = 0.0254 / 0.45

# --------------------------------------------------------------------------- fixtures

# A two-bone chain along +x. "lower" has its local x axis along world y (axis 0 0 90), so
# its single dof rx turns it about world y.
CHAIN_ASF = """\
# two-bone chain
:version 1.10
:name chain
:units
  mass 1.0
  length 1.0
  angle deg
:documentation
   hand-written test skeleton
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name upper
     direction 1 0 0
     length 2
     axis 0 0 0  XYZ
    dof rx ry rz
    limits (-180.0 180.0)
           (-180.0 180.0)
           (-180.0 180.0)
  end
  begin
     id 2
     name lower
     direction 1 0 0
     length 1
     axis 0 0 90  XYZ
    dof rx
    limits (-180.0 180.0)
  end
:hierarchy
  begin
    root upper
    upper lower
  end
"""

CHAIN_AMC = """\
#!OML:ASF chain.asf
:FULLY-SPECIFIED
:DEGREES
1
root 0 0 0 0 0 0
upper 0 0 0
lower 0
2
root 0 0 0 0 0 0
upper 0 0 90
lower 0
3
root 0 0 0 0 0 0
upper 0 0 0
lower 90
4
root 1 2 3 0 90 0
upper 0 0 90
lower 0
"""


def write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.fixture
def chain(tmp_path):
    return write(tmp_path / "chain.asf", CHAIN_ASF), write(tmp_path / "chain_01.amc", CHAIN_AMC)


# A small CMU-like body, in CMU ASF units (1/0.45 inch): name, parent, direction, length,
# dofs. The right side mirrors the left (x -> -x).
_LEFT = [
    ("lhipjoint", "root", (1, -1, 0), 1.5, ""),
    ("lfemur", "lhipjoint", (0, -1, 0), 7.5, "rx ry rz"),
    ("ltibia", "lfemur", (0, -1, 0), 7.5, "rx"),
    ("lfoot", "ltibia", (0, -0.3, 1), 2.0, "rx"),
    ("lclavicle", "lowerback", (1, 0.2, 0), 3.0, ""),
    ("lhumerus", "lclavicle", (1, 0, 0), 5.0, "rx ry rz"),
    ("lradius", "lhumerus", (1, 0, 0), 4.5, "rx"),
    ("lwrist", "lradius", (1, 0, 0), 1.0, "ry"),
    ("lhand", "lwrist", (1, 0, 0), 1.0, "rx rz"),
]
BODY = (
    [
        ("lowerback", "root", (0, 1, 0), 8.0, "rx ry rz"),
        ("head", "lowerback", (0, 1, 0), 3.0, "rx ry rz"),
    ]
    + _LEFT
    + [
        ("r" + n[1:], p if p in ("root", "lowerback") else "r" + p[1:], (-d[0], d[1], d[2]), ln, f)
        for n, p, d, ln, f in _LEFT
    ]
)


def body_asf():
    out = [
        ":version 1.10",
        ":name body",
        ":units",
        "  mass 1.0",
        "  length 0.45",
        "  angle deg",
        ":root",
        "   order TX TY TZ RX RY RZ",
        "   axis XYZ",
        "   position 0 0 0",
        "   orientation 0 0 0",
        ":bonedata",
    ]
    for i, (name, _, d, length, dofs) in enumerate(BODY, 1):
        out += [
            "  begin",
            f"     id {i}",
            f"     name {name}",
            f"     direction {d[0]} {d[1]} {d[2]}",
            f"     length {length}",
            "     axis 0 0 0  XYZ",
        ]
        out += [f"    dof {dofs}"] if dofs else []
        out += ["  end"]
    out += [":hierarchy", "  begin"]
    for parent in ["root"] + [b[0] for b in BODY]:
        children = [b[0] for b in BODY if b[1] == parent]
        out += [f"    {parent} {' '.join(children)}"] if children else []
    return "\n".join(out + ["  end", ""])


def body_amc(frames):
    """frames: list of (root (6,), {bone: angles}) -> AMC text; other bones get zeros."""
    out = [":FULLY-SPECIFIED", ":DEGREES"]
    for i, (root, angles) in enumerate(frames, 1):
        out += [str(i), "root " + " ".join(map(str, root))]
        for name, _, _, _, dofs in BODY:
            if dofs:
                values = angles.get(name, [0.0] * len(dofs.split()))
                out.append(name + " " + " ".join(map(str, values)))
    return "\n".join(out + [""])


def body_bvh(frames, fps=120):
    """The same body as a CMU-named BVH: every rotation is ZYX about moving axes, which is
    the ASF's rx ry rz about fixed axes, so both files describe the same motion."""
    vec = {n: np.array(d, float) / np.linalg.norm(d) * ln for n, _, d, ln, _ in BODY}
    parent = {n: p for n, p, _, _, _ in BODY}
    root_channels = "Xposition Yposition Zposition Zrotation Yrotation Xrotation"
    lines = ["HIERARCHY", "ROOT hip", "{", "  OFFSET 0 0 0", f"  CHANNELS 6 {root_channels}"]

    def joint(name, depth):
        pad = "  " * depth
        off = vec[parent[name]] if parent[name] != "root" else np.zeros(3)
        lines.extend(
            [
                f"{pad}JOINT {name}",
                f"{pad}{{",
                f"{pad}  OFFSET {off[0]} {off[1]} {off[2]}",
                f"{pad}  CHANNELS 3 Zrotation Yrotation Xrotation",
            ]
        )
        children = [n for n, p, _, _, _ in BODY if p == name]
        for child in children:
            joint(child, depth + 1)
        if not children:
            v = vec[name]
            lines.extend(
                [
                    f"{pad}  End Site",
                    f"{pad}  {{",
                    f"{pad}    OFFSET {v[0]} {v[1]} {v[2]}",
                    f"{pad}  }}",
                ]
            )
        lines.append(f"{pad}}}")

    for name in [n for n, p, _, _, _ in BODY if p == "root"]:
        joint(name, 1)
    lines += ["}", "MOTION", f"Frames: {len(frames)}", f"Frame Time: {1 / fps:.8f}"]
    order = ["hip"] + [n for n in (line.split()[1] for line in lines if "JOINT" in line)]
    for root, angles in frames:
        row = list(root[:3]) + list(root[3:][::-1])  # Z Y X
        for name in order[1:]:
            names = next(b[4] for b in BODY if b[0] == name).split()
            dofs = dict(zip(names, angles.get(name, [0.0] * len(names)), strict=True))
            row += [dofs.get("rz", 0.0), dofs.get("ry", 0.0), dofs.get("rx", 0.0)]
        lines.append(" ".join(f"{v:.6f}" for v in row))
    return "\n".join(lines + [""])


def random_frames(rng, n, still=0):
    """n frames of random root motion and joint angles, then ``still`` copies of the last."""
    frames = []
    for i in range(n):
        root = [0.05 * i, 17.0, 0.0, *rng.uniform(-40, 40, 3)]  # walking 0.34 m/s along x
        angles = {b[0]: list(rng.uniform(-60, 60, len(b[4].split()))) for b in BODY if b[4]}
        frames.append((root, angles))
    return frames + [frames[-1]] * still


# BVH: hips at the root, a thigh+shin chain down (80 + 80 cm) and a short spine up (10 + 5).
def chain_bvh(cm=1.0, thigh="Zrotation Xrotation Yrotation", rows=None):
    """Lengths written in units of ``cm`` centimetres."""
    u = 1.0 / cm
    rows = rows or [
        [0, 160 * u, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        [10 * u, 160 * u, 0, 0, 0, 0, 0, 90, 0, 0, 0, 0],
        [0, 160 * u, 0, 90, 0, 0, 0, 0, 0, 0, 0, 0],
    ]
    body = "\n".join(" ".join(f"{v:g}" for v in r) for r in rows)
    return f"""HIERARCHY
ROOT hips
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT thigh
  {{
    OFFSET 0 {-80 * u:g} 0
    CHANNELS 3 {thigh}
    End Site
    {{
      OFFSET 0 {-80 * u:g} 0
    }}
  }}
  JOINT spine
  {{
    OFFSET 0 {10 * u:g} 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {{
      OFFSET 0 {5 * u:g} 0
    }}
  }}
}}
MOTION
Frames: {len(rows)}
Frame Time: 0.0333333
{body}
"""


# ---------------------------------------------------------------------- ASF/AMC + FK


def test_asf_chain_known_positions(chain):
    m = load_asf_amc(*chain, scale=1.0)
    assert m.names == ("root", "upper", "lower", "lower_end")
    assert m.parents == (-1, 0, 1, 2)
    assert m.positions.shape == (4, 4, 3) and m.rotations.shape == (4, 4, 3, 3)
    expected_y_up = np.array(
        [
            [[0, 0, 0], [0, 0, 0], [2, 0, 0], [3, 0, 0]],
            [[0, 0, 0], [0, 0, 0], [0, 2, 0], [0, 3, 0]],  # upper rz 90: +x -> +y
            [[0, 0, 0], [0, 0, 0], [2, 0, 0], [2, 0, -1]],  # lower rx 90 about its x = world y
            [[1, 2, 3], [1, 2, 3], [1, 4, 3], [1, 5, 3]],  # root ry 90 keeps +y
        ],
        dtype=float,
    )
    assert np.allclose(m.positions, expected_y_up @ A.T, atol=1e-9)
    # z up: the chain raised by upper rz 90 points up.
    assert np.allclose(m.positions[1, 3], [0, 0, 3])


def test_asf_rotations_match_scipy_fixed_axes(tmp_path):
    amc = "1\nroot 0 0 0 0 0 0\nupper 0 0 0\nlower 0\n"
    amc += "2\nroot 0 0 0 10 20 30\nupper 40 -50 60\nlower 0\n"
    m = load_asf_amc(
        write(tmp_path / "c.asf", CHAIN_ASF), write(tmp_path / "c.amc", amc), scale=1.0
    )
    R_root = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    R_upper = R_root @ Rotation.from_euler("xyz", [40, -50, 60], degrees=True).as_matrix()
    assert np.allclose(m.rotations[1, 0], A @ R_root @ A.T)
    assert np.allclose(m.rotations[1, 1], A @ R_upper @ A.T)
    assert np.allclose(m.positions[1, 2], A @ R_upper @ [2, 0, 0])
    # rotations are rest-relative: rest direction -> current direction
    assert np.allclose(m.rotations[0], np.eye(3))


def test_asf_radians_header(tmp_path):
    amc = CHAIN_AMC.replace(":DEGREES", ":RADIANS").replace(
        "upper 0 0 90", f"upper 0 0 {np.pi / 2}"
    )
    m = load_asf_amc(
        write(tmp_path / "c.asf", CHAIN_ASF), write(tmp_path / "c.amc", amc), scale=1.0
    )
    assert np.allclose(m.positions[1, 3], [0, 0, 3])


def test_asf_unit_rule_and_bone_lengths(tmp_path):
    asf = write(tmp_path / "01.asf", body_asf())
    frames = random_frames(np.random.default_rng(0), 5)
    m = load_asf_amc(asf, write(tmp_path / "01_01.amc", body_amc(frames)))
    assert m.scale == pytest.approx(CMU_UNIT)  # ':units length 0.45' -> inch / 0.45
    femur = np.linalg.norm(
        m.positions[:, m.index("ltibia")] - m.positions[:, m.index("lfemur")], axis=-1
    )
    assert np.allclose(femur, 7.5 * CMU_UNIT)
    assert 1.0 < np.ptp(m.rest[:, 2]) < 2.0


def test_asf_stated_unit_falls_back_when_implausible(tmp_path):
    asf = write(tmp_path / "01.asf", body_asf().replace("length 0.45", "length 0.1"))
    m = load_asf_amc(
        asf, write(tmp_path / "01_01.amc", body_amc(random_frames(np.random.default_rng(0), 2)))
    )
    assert m.scale == pytest.approx(LENGTH_UNITS["cmu"])  # 1/0.1 inch would be a 7 m giant


def test_asf_and_bvh_of_the_same_motion_agree(tmp_path):
    frames = random_frames(np.random.default_rng(1), 6)
    a = load_asf_amc(
        write(tmp_path / "01.asf", body_asf()), write(tmp_path / "01_01.amc", body_amc(frames))
    )
    b = load_bvh(write(tmp_path / "01_01.bvh", body_bvh(frames)))
    assert b.scale == pytest.approx(CMU_UNIT)  # detected from the rest height
    assert set(a.names) == set(b.names) - {"hip"} | {"root"}
    for name in ("lfemur", "rtibia", "lfoot", "rhumerus", "lhand", "head", "head_end"):
        assert np.allclose(
            a.positions[:, a.index(name)], b.positions[:, b.index(name)], atol=1e-5
        ), name
        assert np.allclose(
            a.rotations[:, a.index(name)], b.rotations[:, b.index(name)], atol=1e-6
        ), name
    assert np.allclose(to_coco17(a), to_coco17(b), atol=1e-5)


# ---------------------------------------------------------------------------------- BVH


def test_bvh_chain(tmp_path):
    m = load_bvh(write(tmp_path / "c.bvh", chain_bvh()))
    assert m.names == ("hips", "thigh", "thigh_end", "spine", "spine_end")
    assert m.fps == 30.0 and m.scale == 0.01
    assert load_bvh(tmp_path / "c.bvh", fps=120.0).fps == 120.0  # a wrong Frame Time fixed
    knee_y_up = np.array([[0, 0, 0], [0.1, 0.8, -0.8], [1.6, 1.6, 0]])  # thigh_end, metres
    assert np.allclose(m.positions[:, 2], knee_y_up @ A.T)
    assert np.allclose(m.positions[1, 2], [0.1, 0.8, 0.8])  # x rotation 90 swings it back
    # z up: at rest the head end is above the hips, the knee below
    assert m.positions[0, 4, 2] > m.positions[0, 0, 2] > m.positions[0, 2, 2]


@pytest.mark.parametrize("cm, unit", [(1.0, "cm"), (100.0, "m"), (2.54, "inch"), (0.1, "mm")])
def test_bvh_unit_detection(tmp_path, cm, unit):
    m = load_bvh(write(tmp_path / "c.bvh", chain_bvh(cm)))
    ref = load_bvh(write(tmp_path / "ref.bvh", chain_bvh()))
    assert m.scale == pytest.approx(LENGTH_UNITS[unit])
    assert np.allclose(m.positions, ref.positions, atol=1e-5)  # 6 digits written
    assert np.ptp(m.rest[:, 2]) == pytest.approx(1.75, abs=1e-4)


def test_bvh_implausible_height_needs_scale(tmp_path):
    path = write(tmp_path / "c.bvh", chain_bvh(175 / 17))  # 17 units tall: no unit fits
    with pytest.raises(InputError, match="c.bvh.*scale="):
        load_bvh(path)
    assert load_bvh(path, scale=0.1).scale == 0.1


@pytest.mark.parametrize(
    "order",
    [
        "Zrotation Xrotation Yrotation",
        "Yrotation Zrotation Xrotation",
        "Xrotation Yrotation Zrotation",
    ],
)
def test_bvh_rotation_order_matches_scipy_moving_axes(tmp_path, order):
    angles = [30.0, -50.0, 70.0]
    rows = [[0, 160, 0, 0, 0, 0, *angles, 0, 0, 0]]
    m = load_bvh(write(tmp_path / "c.bvh", chain_bvh(thigh=order, rows=rows)))
    R = Rotation.from_euler("".join(c[0] for c in order.split()), angles, degrees=True).as_matrix()
    assert np.allclose(m.rotations[0, 1], A @ R @ A.T)
    assert np.allclose(m.positions[0, 2], [0, 0, 0.8] + A @ R @ [0, -0.8, 0])


def test_z_up_is_a_proper_rotation():
    assert np.allclose(A @ A.T, np.eye(3)) and np.linalg.det(A) == pytest.approx(1.0)
    assert np.allclose(A @ [0, 1, 0], [0, 0, 1])  # y up -> z up


def test_detect_length_unit():
    assert detect_length_unit(1.7) == ("m", 1.0)
    assert detect_length_unit(1700)[0] == "mm"
    assert detect_length_unit(30)[0] == "cmu"


# --------------------------------------------------------------------------- bad input


def bad(tmp_path, name, text, loader, *match):
    path = write(tmp_path / name, text)
    with pytest.raises(InputError) as info:
        loader(path)
    message = str(info.value)
    assert name in message
    for m in match:
        assert m in message, message
    return message


def test_bvh_wrong_channel_count(tmp_path):
    text = chain_bvh().replace(
        "CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Xrotation"
    )
    bad(tmp_path, "c.bvh", text, load_bvh, "line 9", "CHANNELS")


def test_bvh_wrong_value_count(tmp_path):
    lines = chain_bvh().splitlines()
    lines[-2] = lines[-2] + " 0"  # second frame, 13 values for 12 channels
    bad(tmp_path, "c.bvh", "\n".join(lines), load_bvh, f"line {len(lines) - 1}", "12 values")


def test_bvh_bad_number_and_truncation(tmp_path):
    lines = chain_bvh().splitlines()
    bad(
        tmp_path,
        "a.bvh",
        "\n".join(lines[:-1] + [lines[-1].replace("90", "9o")]),
        load_bvh,
        f"line {len(lines)}",
    )
    bad(tmp_path, "b.bvh", "\n".join(lines[:-1]), load_bvh, "Frames", "truncated")
    bad(tmp_path, "c.bvh", "\n".join(lines[:12]), load_bvh, "MOTION")


def test_amc_unknown_bone(tmp_path, chain):
    asf, _ = chain
    text = CHAIN_AMC.replace("lower 90", "elbow 90")
    bad(tmp_path, "x.amc", text, lambda p: load_asf_amc(asf, p, scale=1.0), "line 15", "got elbow")


def test_amc_truncated_and_wrong_count(tmp_path, chain):
    asf, _ = chain
    load = lambda p: load_asf_amc(asf, p, scale=1.0)  # noqa: E731
    truncated = CHAIN_AMC.rsplit("lower", 1)[0]
    bad(tmp_path, "t.amc", truncated, load, "line 16", "'lower'", "truncated")
    bad(
        tmp_path,
        "w.amc",
        CHAIN_AMC.replace("upper 0 0 90", "upper 0 90"),
        load,
        "line 10",
        "3 values",
    )


def test_asf_bad_input(tmp_path):
    cut = CHAIN_ASF.split("     name lower")[0]
    bad(tmp_path, "cut.asf", cut, read_asf, ":hierarchy")
    no_end = CHAIN_ASF.replace("    limits (-180.0 180.0)\n  end\n:hierarchy", "\n:hierarchy")
    bad(tmp_path, "noend.asf", no_end, read_asf, "'end'")
    orphan = CHAIN_ASF.replace("    upper lower\n", "")
    bad(tmp_path, "orphan.asf", orphan, read_asf, "lower")
    stray = CHAIN_ASF.replace("root upper", "root upper knee")
    bad(tmp_path, "stray.asf", stray, read_asf, "knee", "line")
    degrees = CHAIN_ASF.replace("angle deg", "angle gon")
    bad(tmp_path, "gon.asf", degrees, read_asf, "angle", "line 7")


# --------------------------------------------------------------------------- COCO-17


def test_coco_rest_pose_face_and_hips(tmp_path):
    frames = [([0, 17, 0, 0, 0, 0], {}), ([0, 17, 0, 0, 0, 0], {"head": [0, 90, 0]})]
    m = load_asf_amc(
        write(tmp_path / "01.asf", body_asf()), write(tmp_path / "01_01.amc", body_amc(frames))
    )
    coco = to_coco17(m)
    head = m.positions[:, m.index("head")]
    # rest: the person faces -y with their left along +x (ASF: +z forward, +x left, y up)
    nose = FACE_OFFSETS["nose"]
    assert np.allclose(coco[0, 0], head[0] + [0, -nose[1], 0.06 + nose[2]])
    assert coco[0, 1, 0] > coco[0, 2, 0] and coco[0, 3, 0] - coco[0, 4, 0] == pytest.approx(0.15)
    out, _, up = HIP_OFFSET
    assert np.allclose(coco[0, 11], m.positions[0, m.index("lfemur")] + [out, 0, up])
    assert np.allclose(coco[0, 12], m.positions[0, m.index("rfemur")] + [-out, 0, up])
    assert np.allclose(coco[0, 15], m.positions[0, m.index("lfoot")])
    # head turned 90 deg to the person's left (about the vertical): the nose points +x
    assert np.allclose(coco[1, 0], head[1] + [nose[1], 0, 0.06 + nose[2]])
    assert np.allclose(coco[1, 3], head[1] + [0, 0.075, 0.06])  # left ear now behind


def test_mirror_is_an_involution_and_swaps_sides():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(5, 17, 3))
    assert np.allclose(mirror(mirror(p)), p)
    q = mirror(p)
    mid = p[:, 11:13].mean(axis=1)
    assert np.allclose(q[:, 11:13].mean(axis=1), mid)  # the pelvis stays put
    assert np.allclose(q[:, 6, 1:], p[:, 5, 1:])  # right shoulder = left one, reflected in x
    assert np.allclose(q[:, 6, 0], 2 * mid[:, 0] - p[:, 5, 0])
    assert np.allclose(q[:, 0, 0], 2 * mid[:, 0] - p[:, 0, 0])  # the nose has no partner
    assert np.allclose(q[:, 0, 1:], p[:, 0, 1:])
    bones = np.array(COCO17.bones)
    length = lambda x: np.linalg.norm(x[:, bones[:, 0]] - x[:, bones[:, 1]], axis=-1)  # noqa: E731
    assert np.allclose(np.sort(length(q), axis=1), np.sort(length(p), axis=1))


# --------------------------------------------------------------------------- pose sets


def test_usable_frames_drop_rest_blend_and_glitches(tmp_path):
    rng = np.random.default_rng(3)
    rest_first = [([0, 17, 0, 0, 0, 0], {})] + random_frames(rng, 70)
    keep = usable_frames(load_bvh(write(tmp_path / "a.bvh", body_bvh(rest_first))))
    assert keep.tolist() == [False] * 6 + [True] * 65  # 50 ms at 120 fps
    far = [([r[0] + 500, *r[1:]], a) for r, a in random_frames(rng, 3)]  # 28 m away
    m = load_bvh(write(tmp_path / "b.bvh", body_bvh(far + random_frames(rng, 70))))
    assert usable_frames(m).tolist() == [False] * 3 + [True] * 70
    assert not usable_frames(m, min_duration=1.0).any()


@pytest.fixture
def motion_root(tmp_path):
    rng = np.random.default_rng(2)
    root = tmp_path / "mocap"
    write(root / "asfamc" / "07" / "07.asf", body_asf())
    write(root / "asfamc" / "07" / "07_01.amc", body_amc(random_frames(rng, 30, still=30)))
    write(root / "bvh" / "dance" / "salsa" / "01.bvh", body_bvh(random_frames(rng, 61)))
    write(root / "bvh" / "dance" / "standard.bvh", body_bvh(random_frames(rng, 3), fps=30))
    return root


def test_find_clips_subjects(motion_root):
    clips = find_clips(motion_root)
    assert [(c.subject, c.clip) for c in clips] == [
        ("07", "asfamc/07/07_01.amc"),
        ("dance-salsa", "bvh/dance/salsa/01.bvh"),
        ("bvh-dance", "bvh/dance/standard.bvh"),
    ]
    assert clips[0].asf == motion_root / "asfamc" / "07" / "07.asf"
    assert [c.subject for c in find_clips(motion_root, ["dance-salsa"])] == ["dance-salsa"]


def test_load_motion_dir_subsamples_dedups_and_grounds(motion_root):
    every = load_motion_dir(motion_root, fps=10.0, min_move=0.0)
    # 60 frames at 120 fps -> frames 0, 12, 24, 36, 48; 61 frames -> also 60; the 3-frame
    # reference pose is skipped.
    assert every.frame.tolist() == [0, 12, 24, 36, 48, 0, 12, 24, 36, 48, 60]
    assert every.subject.tolist() == ["07"] * 5 + ["dance-salsa"] * 6
    assert every.poses.dtype == np.float32 and every.poses.shape == (11, 17, 3)
    deduped = load_motion_dir(motion_root, fps=10.0)
    assert deduped.frame.tolist() == [0, 12, 24, 36, 0, 12, 24, 36, 48, 60]  # 48 repeats 36
    assert load_motion_dir(motion_root, fps=20.0, min_move=0.0).frame.tolist()[:3] == [0, 6, 12]
    assert len(load_motion_dir(motion_root, subjects=["07"])) == 4
    with pytest.raises(InputError, match="subjects"):
        load_motion_dir(motion_root, subjects=["99"])
    assert set(load_motion_dir(motion_root, exclude=["salsa/01.bvh"]).subject) == {"07"}


def test_pose_set_roundtrip_split_and_bad_file(tmp_path, motion_root):
    out = build_pose_cache(motion_root, tmp_path / "cache", holdout_subjects=("07",))
    train, val = load_pose_set(out["train"]), load_pose_set(out["val"])
    assert set(train.subject) == {"dance-salsa"} and set(val.subject) == {"07"}
    full = load_motion_dir(motion_root)
    both = PoseSet.concatenate([train, val])
    assert len(both) == len(full)
    assert np.array_equal(np.sort(both.poses.ravel()), np.sort(full.poses.ravel()))
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["train.npz", "val.npz"]
    save_pose_set(tmp_path / "x.npz", val)
    again = load_pose_set(tmp_path / "x.npz")
    assert np.array_equal(again.poses, val.poses) and again.clip.tolist() == val.clip.tolist()
    bad(tmp_path, "junk.npz", "not a zip", load_pose_set)
    np.savez(tmp_path / "other.npz", poses=np.zeros((1, 17, 3)))
    with pytest.raises(InputError, match="format"):
        load_pose_set(tmp_path / "other.npz")


# ------------------------------------------------------------------------ shared data

CMU = "cmu_mocap"


def _real_clips(root):
    asf = root / CMU / "asfamc/data/CMU/asfamc/subjects/02"
    bvh = root / CMU / "bvh"
    return {
        "asf 02_01": lambda: load_asf_amc(asf / "02.asf", asf / "02_01.amc"),
        "daz 02_01": lambda: load_bvh(bvh / "misc/data/02/02_01.bvh"),
        "cmu-bvh 16_01": lambda: load_bvh(bvh / "misc/data/16/16_01.bvh"),
        "salsa 01": lambda: load_bvh(bvh / "dance/salsa/01.bvh"),
    }


def _unit(v):
    v = v * [1, 1, 0]
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@pytest.mark.shared
def test_real_clips_are_human(shared_data):
    for name, load in _real_clips(shared_data).items():
        m = load()
        coco = to_coco17(m)
        floor = floor_height(m.positions)
        assert abs(floor) < 0.1, name  # these clips were captured on z = 0
        eyes = np.percentile(coco[:, 1:3, 2].mean(axis=1), 90) - floor
        assert 1.4 < eyes + 0.11 < 2.0, name  # stature ~ eye height + 11 cm
        ankles = coco[:, 15:17, 2].min(axis=1) - floor
        assert 0.0 < np.median(ankles) < 0.15, name  # a foot on the floor
        parents = np.array(m.parents)
        lengths = np.linalg.norm(m.positions[:, 1:] - m.positions[:, parents[1:]], axis=-1)
        assert lengths.std(axis=0).max() < 1e-3, name
        limbs = np.array([(5, 7), (6, 8), (7, 9), (8, 10), (13, 15), (14, 16)])
        coco_lengths = np.linalg.norm(coco[:, limbs[:, 0]] - coco[:, limbs[:, 1]], axis=-1)
        assert coco_lengths.std(axis=0).max() < 1e-3, name
        assert 0.2 < coco_lengths.mean(axis=0).min() and coco_lengths.mean(axis=0).max() < 0.5, name


@pytest.mark.shared
def test_real_clips_left_is_left(shared_data):
    for name, load in _real_clips(shared_data).items():
        m = load()
        coco = to_coco17(m)
        facing = _unit(coco[:, 0] - coco[:, 3:5].mean(axis=1))  # from the nose
        left = np.cross([0.0, 0.0, 1.0], facing)  # the person's left
        assert (np.sum((coco[:, 5] - coco[:, 6]) * left, axis=-1) > 0).mean() > 0.95, name
        assert (np.sum((coco[:, 11] - coco[:, 12]) * left, axis=-1) > 0).mean() > 0.95, name
        cmu = "ltoes" in m.names
        toes = [m.index(n) for n in (("ltoes", "rtoes") if cmu else ("lFoot_end", "rFoot_end"))]
        ankles = [m.index(n) for n in (("lfoot", "rfoot") if cmu else ("lFoot", "rFoot"))]
        feet = _unit((m.positions[:, toes] - m.positions[:, ankles]).mean(axis=1))
        assert (np.sum(feet * facing, axis=-1) > 0).mean() > 0.9, (
            name
        )  # toes point where the nose does


@pytest.mark.shared
def test_real_daz_bvh_starts_with_a_rest_pose_blend(shared_data):
    m = _real_clips(shared_data)["daz 02_01"]()
    keep = usable_frames(m)
    assert not keep[:6].any() and keep[6:].all()
    rel = np.einsum("tji,tkj->tki", m.rotations[:, 0], m.positions - m.positions[:, :1])
    deviation = np.linalg.norm(rel - m.rest, axis=-1).max(axis=1)  # from the rest pose
    assert deviation[0] < 0.05 and deviation[6:].min() > 0.2


@pytest.mark.shared
def test_real_directory_subset(shared_data):
    root = shared_data / CMU
    subjects = ["02", "16"]
    clips = find_clips(root, subjects)
    kinds = {c.clip.split("/")[0] for c in clips}
    assert kinds == {"asfamc", "bvh"}
    every = load_motion_dir(root, subjects, fps=10.0, min_move=0.0)
    frames = {}
    for c in clips:  # one pose per 1/10 s of the usable part of every clip
        rate = next((v for k, v in FRAME_RATES.items() if c.clip.endswith(k)), None)
        m = load_asf_amc(c.asf, c.path) if c.asf else load_bvh(c.path, fps=rate)
        frames[c.clip] = np.count_nonzero(usable_frames(m)[:: round(m.fps / 10)])
    assert len(every) == sum(frames.values())
    poses = load_motion_dir(root, subjects)
    assert 0.5 * len(every) < len(poses) <= len(every)
    assert set(poses.subject) == set(subjects)
    assert np.isfinite(poses.poses).all()
    for clip in frames:  # grounded: the lower ankle of a clip's frames ~ 4-15 cm up
        ankles = poses.poses[poses.clip == clip][:, 15:17, 2].min(axis=1)
        assert 0.0 < np.median(ankles) < 0.15, clip
