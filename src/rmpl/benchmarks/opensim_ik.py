"""OpenSim scaling + inverse kinematics (through Pose2Sim) on rmpl's per-person TRC files.

For each input (an rmpl run's ``poses.npz``: the lifter, ``--method triangulate``,
``--method robust``, ... of the same recording) this command

1. picks one person: ``--person`` in the first input, the nearest track (mean distance of
   the hip midpoint over shared frames) in the others;
2. writes that person's Pose2Sim files (:func:`rmpl.io.pose2sim.write_pose2sim`: COCO_17
   marker names for COCO-17 poses, HALPE_26 ones (with heels and toes) for HALPE-26 poses;
   Pose2Sim's Y-up axes, metres) into ``OUT/<label>-<markerset>/pose-3d/``;
3. runs ``Pose2Sim.kinematics()`` there in the OpenSim venv (scripts/setup_opensim.sh):
   the pose model the TRC's markers name (``HALPE_26`` when it has ``LHeel``, else
   ``COCO_17``), no marker augmentation, the participant's height and mass;
4. reads OpenSim's outputs: the IK marker error of every frame (``_ik_marker_errors.sto``,
   RMS over markers and the largest marker error) and the joint angles (``.mot``).

The participant's height is ``--height``, else :func:`rmpl.anthropometry.estimate_height`
of the first input's track (the same height for every input, so that only the markers
differ). Pose2Sim's scaling takes segment lengths from the markers; the height enters the
scaled model's record only, the mass its segment masses.

Marker sets (``--markerset``): ``shipped`` is Pose2Sim's ``Markers_Coco17.xml`` as
installed. In Pose2Sim 0.10.49 its ``RHip`` sits on the pelvis at (-0.005, -0.398, -0.001) m,
the left knee marker's femur coordinates, 0.4 m below the hip joint, while ``LHip`` is at
(-0.064, -0.081, -0.105) m as in every other Pose2Sim marker set; ``fixed`` runs the same
setup with ``RHip`` at ``LHip`` mirrored (z -> -z), written into a copy of the setup folder
(the installed package is not changed). ``Markers_Halpe26.xml`` has ``RHip`` right, so for
HALPE-26 poses both marker sets are the same (give ``--markerset shipped``).

Joint-angle plausibility: the share of frames in which a hip, knee or elbow angle lies
outside the normal range of motion of the American Academy of Orthopaedic Surgeons (Greene
& Heckman, *The Clinical Measurement of Joint Motion*, AAOS 1994): hip flexion 120,
extension 30, abduction 45, adduction 30, internal and external rotation 45 degrees; knee
flexion 135 (extension 0, with 10 degrees of hyperextension allowed); elbow flexion 150
(same allowance). In the OpenSim model's signs: hip_flexion in [-30, 120], hip_adduction in
[-45, 30], hip_rotation in [-45, 45], knee_angle in [-10, 135], elbow_flex in [-10, 150].
The model clamps its coordinates (knee 0-155, elbow 0-150, hip flexion -50-150, adduction
-60-30, rotation -70-40), so IK cannot go beyond those. Without heels and toes the ankle,
subtalar and MTP angles are not driven (they stay 0) and are not scored; with HALPE_26's heel
and toe markers they are, and ``ankle_range`` / ``subtalar_range`` / ``mtp_range`` report
their ranges over the trial (degrees, both sides).

Smoothness: the RMS angular acceleration of the knee, hip flexion and elbow angles, second
differences times fps squared, degrees / s^2 (lower is smoother).

Usage (rmpl's venv; the OpenSim venv from scripts/setup_opensim.sh)::

    python -m rmpl.benchmarks.opensim_ik --poses rmpl=demo_rmpl/poses.npz \\
        triangulate=demo_triangulate/poses.npz robust=demo_robust/poses.npz \\
        --person 0 --out ik_demo/ [--height 1.75] [--mass 70] [--markerset both]

The inputs may mix joint sets (a HALPE-26 lifter beside COCO-17 triangulation): each is
written and solved with its own pose model.

It prints a markdown table and writes ``OUT/results.json``. A finished input is not run
again (``OUT/<label>-<markerset>/result.json``); ``--force`` runs it anew.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

log = logging.getLogger("opensim_ik")

#: The checkout: src/rmpl/benchmarks/opensim_ik.py is three folders below it.
REPO = Path(__file__).resolve().parents[3]
MARKERSETS = ("shipped", "fixed")
#: AAOS normal range of motion in the OpenSim model's signs, degrees (see the docstring).
RANGES = {
    "hip_flexion": (-30.0, 120.0),
    "hip_adduction": (-45.0, 30.0),
    "hip_rotation": (-45.0, 45.0),
    "knee_angle": (-10.0, 135.0),
    "elbow_flex": (-10.0, 150.0),
}
SMOOTH = ("knee_angle", "hip_flexion", "elbow_flex")


# --------------------------------------------------------------------------- the OpenSim side


def trc_pose_model(project: Path) -> str:
    """Pose2Sim's pose model for the TRC files of ``project/pose-3d``, by their markers:
    ``HALPE_26`` when they have heels (rmpl writes them for HALPE-26 poses), else
    ``COCO_17``."""
    names: set[str] = set()
    for trc in sorted((project / "pose-3d").glob("*.trc")):
        with open(trc, encoding="utf-8") as f:
            header = [next(f) for _ in range(4)]
        names |= {m.strip() for m in header[3].split("\t")[2:] if m.strip()}
    return "HALPE_26" if {"LHeel", "RHeel", "Head"} <= names else "COCO_17"


def worker(project: Path, height: float, mass: float, markerset: str, augment: bool) -> None:
    """In the OpenSim venv: Pose2Sim's kinematics on ``project/pose-3d/*.trc``, with the pose
    model their markers name (:func:`trc_pose_model`)."""
    import Pose2Sim.kinematics as kin
    from Pose2Sim import Pose2Sim

    if markerset == "fixed":
        kin.get_opensim_setup_dir = lambda: _fixed_setup(project)
    config = {
        "project": {
            "project_dir": str(project),
            "multi_person": False,
            "participant_height": height,
            "participant_mass": mass,
        },
        "pose": {"pose_model": trc_pose_model(project)},
        "kinematics": {"use_augmentation": False, "parallel_workers_kinematics": False},
    }
    if augment:  # the LSTM marker augmenter: record what it does without feet
        (project / "augmenter.txt").write_text(_augment(Pose2Sim, config, project))
    Pose2Sim.kinematics(config)


def _augment(Pose2Sim, config: dict, project: Path) -> str:
    """Run Pose2Sim's marker augmenter; its warnings or error and the markers it wrote. Its
    output (``*_LSTM.trc``) is moved aside, so that the kinematics reads rmpl's TRC."""
    from Pose2Sim.common import read_trc

    said: list[str] = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = lambda record: said.append(record.getMessage())
    logging.getLogger().addHandler(handler)
    try:
        Pose2Sim.markerAugmentation(config)
        said.append("finished")
    except Exception as e:  # noqa: BLE001  recorded, not fatal
        said.append(f"{type(e).__name__}: {e}")
    finally:
        logging.getLogger().removeHandler(handler)
    aside = project / "augmenter"
    aside.mkdir(exist_ok=True)
    for f in sorted((project / "pose-3d").glob("*_LSTM*")):
        if f.suffix == ".trc":
            said.append(f"{f.name}: markers {' '.join(read_trc(f)[3])}")
        f.rename(aside / f.name)
    keep = [s for s in said if "GUI not available" not in s and "Config.toml" not in s]
    return "\n".join(keep) + "\n"


def _fixed_setup(project: Path) -> Path:
    """A copy of Pose2Sim's OpenSim_Setup whose Markers_Coco17.xml has RHip = LHip mirrored."""
    from lxml import etree
    from Pose2Sim.common import __file__ as common_file

    shipped = Path(common_file).resolve().parent / "OpenSim_Setup"
    setup = project / "OpenSim_Setup_fixed"
    if not setup.exists():
        setup.mkdir()
        for f in shipped.iterdir():
            (setup / f.name).symlink_to(f)
        (setup / "Markers_Coco17.xml").unlink()
        tree = etree.parse(str(shipped / "Markers_Coco17.xml"))
        markers = {m.get("name"): m for m in tree.getroot().iter("Marker")}
        x, y, z = markers["LHip"].find("location").text.split()
        markers["RHip"].find("location").text = f"{x} {y} {-float(z)!r}"
        tree.write(str(setup / "Markers_Coco17.xml"), xml_declaration=True, encoding="UTF-8")
    return setup


# --------------------------------------------------------------------------- rmpl's side


def pick_people(inputs: dict[str, Path], person: int | None):
    """One person's track per input: ``person`` (or the most complete one) in the first
    input, the track nearest to it in the others. Returns {label: one-person Poses3D}."""
    from rmpl.io.pose2sim import marker_points, pose_model, select_frames
    from rmpl.io.poses import Poses3D, load_poses

    picked, ref = {}, None
    for label, path in inputs.items():
        poses = load_poses(path)
        model = pose_model(poses.skeleton, path)
        hip_index = list(model.markers).index("Hip")
        mk = marker_points(poses.points, poses.joint_names, model.markers, model.fallbacks)
        complete = [len(select_frames(mk[:, p], "complete", model)[0]) for p in range(mk.shape[1])]
        if ref is None:
            ids = poses.person_ids.tolist()
            if person is None:
                p = int(np.argmax(complete))
            elif person in ids:
                p = ids.index(person)
            else:
                from rmpl.errors import InputError

                raise InputError(path, "--person", f"one of the ids {ids}", person)
            ref = dict(zip(poses.frames.tolist(), mk[:, p, hip_index], strict=True))
        else:
            p = _nearest(ref, poses.frames, mk[:, :, hip_index])
        picked[label] = Poses3D(
            poses.points[:, p : p + 1],
            skeleton=poses.skeleton,
            frames=poses.frames,
            fps=poses.fps,
            person_ids=poses.person_ids[p : p + 1],
        )
        log.info(
            "%s: person %d, %d frames with every IK marker", label, poses.person_ids[p], complete[p]
        )
    return picked


def _nearest(ref: dict[int, np.ndarray], frames: np.ndarray, hip: np.ndarray) -> int:
    dist = []
    for p in range(hip.shape[1]):
        d = [np.linalg.norm(hip[i, p] - ref[f]) for i, f in enumerate(frames.tolist()) if f in ref]
        d = [x for x in d if np.isfinite(x)]
        dist.append(np.median(d) if d else np.inf)
    return int(np.argmin(dist))


def height_of(one, given: float | None) -> tuple[float, str]:
    if given is not None:
        return given, "--height"
    from rmpl.anthropometry import estimate_height

    return estimate_height(one.points[:, 0], one.skeleton), "rmpl.anthropometry.estimate_height"


# --------------------------------------------------------------------------- OpenSim's outputs


def read_sto(path: Path) -> tuple[list[str], np.ndarray]:
    """An OpenSim .sto/.mot: column names and data rows (after ``endheader``)."""
    lines = path.read_text().splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.strip() == "endheader") + 1
    names = lines[start].split("\t")
    names = [n.strip() for n in names]
    data = np.array([[float(x) for x in ln.split()] for ln in lines[start + 1 :] if ln.strip()])
    return names, data


def metrics(project: Path, stem: str, fps: float) -> dict:
    kin = project / "kinematics"
    enames, err = read_sto(kin / "_ik_marker_errors.sto")
    rms, mx = err[:, enames.index("marker_error_RMS")], err[:, enames.index("marker_error_max")]
    names, mot = read_sto(kin / f"{stem}.mot")
    angles = {n: mot[:, i] for i, n in enumerate(names)}
    out_any = np.zeros(len(mot), bool)
    share = {}
    for coord, (lo, hi) in RANGES.items():
        outside = np.zeros(len(mot), bool)
        for side in ("r", "l"):
            a = angles[f"{coord}_{side}"]
            outside |= (a < lo) | (a > hi)
        share[coord] = float(outside.mean())
        out_any |= outside
    accel = {}
    for coord in SMOOTH:
        acc = [np.diff(angles[f"{coord}_{s}"], 2) * fps**2 for s in ("r", "l")]
        accel[coord] = float(np.sqrt(np.mean(np.concatenate(acc) ** 2)))
    return dict(
        frames=len(mot),
        rms_mean_cm=100 * float(rms.mean()),
        rms_median_cm=100 * float(np.median(rms)),
        max_cm=100 * float(mx.max()),
        max_p95_cm=100 * float(np.percentile(mx, 95)),
        outside_share=share,
        outside_any=float(out_any.mean()),
        accel_rms=accel,
        knee_range=[
            float(min(angles["knee_angle_r"].min(), angles["knee_angle_l"].min())),
            float(max(angles["knee_angle_r"].max(), angles["knee_angle_l"].max())),
        ],
        ankle_driven=bool(np.any(angles["ankle_angle_r"] != 0)),
        **{
            f"{c}_range": [
                float(min(angles[f"{c}_angle_r"].min(), angles[f"{c}_angle_l"].min())),
                float(max(angles[f"{c}_angle_r"].max(), angles[f"{c}_angle_l"].max())),
            ]
            for c in ("ankle", "subtalar", "mtp")
            if f"{c}_angle_r" in angles
        },
    )


def shelf_truth(root: Path, actor: int, fps: float):
    """Shelf ground truth of one actor (0-based id) as one-person COCO-17 poses: the twelve
    limb joints; nose, eyes and ears missing (Shelf has none), so that IK runs without the
    Nose marker. Frames are Shelf's frame numbers, as ``rmpl run`` numbers them."""
    from rmpl.data.shelf import load_shelf
    from rmpl.io.poses import Poses3D
    from rmpl.skeleton import COCO17, SHELF14

    shelf = load_shelf(root)
    gt = shelf.gt[:, actor]  # (T, 15, 3) m, z up
    points = np.full((len(gt), 1, 17, 3), np.nan)
    for j, name in enumerate(SHELF14.joints[:12]):
        points[:, 0, COCO17.index(name)] = gt[:, j]
    return Poses3D(points, frames=shelf.frames, fps=fps, person_ids=[actor])


def write_truth(one, folder: Path, stem: str) -> Path:
    """The ground truth's TRC: rmpl.io.pose2sim's layout, without the markers Shelf lacks
    (Pose2Sim's scaling fails on a marker that is empty in every frame), every frame with
    both legs."""
    from rmpl.io.atomic import atomic_path
    from rmpl.io.pose2sim import POSE2SIM_MARKERS, marker_points, to_file_axes, trc_text

    mk = marker_points(one.points[:, 0], one.joint_names)  # (T, M, 3)
    seen = np.flatnonzero(np.isfinite(mk).all(-1).any(0))
    names = tuple(np.array(list(POSE2SIM_MARKERS))[seen])
    legs = [names.index(m) for m in ("RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle")]
    mk = mk[:, seen]
    rows = np.flatnonzero(np.isfinite(mk[:, legs]).all((-1, -2)))
    path = folder / f"{stem}_p{one.person_ids[0]}.trc"
    folder.mkdir(parents=True, exist_ok=True)
    text = trc_text(
        to_file_axes(mk[rows], "pose2sim-y-up"), one.frames[rows], one.fps, "m", path.name, names
    )
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def angle_errors(project: Path, stem: str, truth: Path, truth_stem: str) -> dict:
    """RMS difference of the scored joint angles from the ground truth's IK, degrees, over
    the times both have."""
    names, mot = read_sto(project / "kinematics" / f"{stem}.mot")
    tnames, tmot = read_sto(truth / "kinematics" / f"{truth_stem}.mot")
    t, tt = np.round(mot[:, 0], 4), np.round(tmot[:, 0], 4)
    common, i, k = np.intersect1d(t, tt, return_indices=True)
    out = {}
    for coord in RANGES:
        d = [
            mot[i, names.index(f"{coord}_{s}")] - tmot[k, tnames.index(f"{coord}_{s}")]
            for s in ("r", "l")
        ]
        out[coord] = float(np.sqrt(np.mean(np.concatenate(d) ** 2)))
    return dict(frames=len(common), rms_deg=out)


# --------------------------------------------------------------------------- the benchmark


def run_one(label, one, markerset, args, height, python, truth: bool = False) -> dict:
    from rmpl.io.pose2sim import pose_model, write_pose2sim

    project = args.out / f"{label}-{markerset}"
    done = project / "result.json"
    if done.exists() and not args.force:
        return json.loads(done.read_text())
    if project.exists():
        shutil.rmtree(project)
    if truth:
        trc = c3d = write_truth(one, project / "pose-3d", label)
    else:
        trc, c3d = write_pose2sim(one, project / "pose-3d", stem=label, missing=args.missing)
    cmd = [
        str(python),
        str(Path(__file__).resolve()),
        "--worker",
        str(project),
        "--height",
        repr(height),
        "--mass",
        repr(args.mass),
        "--markerset",
        markerset,
    ]
    if args.augmenter and not truth:
        cmd.append("--augmenter")
    env = dict(os.environ, MPLBACKEND="Agg")
    run = subprocess.run(cmd, cwd=project, capture_output=True, text=True, env=env)
    (project / "worker.log").write_text(run.stdout + run.stderr)
    if run.returncode != 0:
        tail = "\n".join((run.stdout + run.stderr).splitlines()[-15:])
        raise SystemExit(f"Pose2Sim kinematics failed for {project}:\n{tail}")
    result = dict(
        label=label,
        markerset=markerset,
        pose_model=pose_model(one.skeleton).name,
        trc=str(trc),
        c3d=str(c3d),
        height=height,
        mass=args.mass,
        **metrics(project, trc.stem, one.fps),
    )
    aug = project / "augmenter.txt"
    if aug.exists():
        result["augmenter"] = aug.read_text().strip()
    done.write_text(json.dumps(result, indent=1))
    return result


def table(results: list[dict]) -> str:
    """The results as markdown: IK marker errors and plausibility, and (with --shelf-gt)
    each joint angle's RMS difference from the ground truth's IK."""
    head = (
        "| input | marker set | frames | IK RMS mean (cm) | IK RMS median | IK max (cm) "
        "| max, 95th pct | frames outside AAOS range: hip fl / add / rot, knee, elbow, any (%) "
        "| knee range (deg) | RMS ang. accel. knee / hip fl / elbow (deg/s^2) |"
    )
    rows = [head, "|" + "---|" * 10]
    for r in results:
        s = r["outside_share"]
        a = r["accel_rms"]
        shares = " / ".join(
            f"{100 * s[k]:.0f}" for k in ("hip_flexion", "hip_adduction", "hip_rotation")
        )
        rows.append(
            f"| {r['label']} | {r['markerset']} | {r['frames']} | {r['rms_mean_cm']:.1f} "
            f"| {r['rms_median_cm']:.1f} | {r['max_cm']:.1f} | {r['max_p95_cm']:.1f} "
            f"| {shares}, {100 * s['knee_angle']:.0f}, {100 * s['elbow_flex']:.0f}, "
            f"{100 * r['outside_any']:.0f} "
            f"| {r['knee_range'][0]:.0f} to {r['knee_range'][1]:.0f} "
            f"| {a['knee_angle']:.0f} / {a['hip_flexion']:.0f} / {a['elbow_flex']:.0f} |"
        )
    feet = [r for r in results if "subtalar_range" in r]
    if feet:
        rows += [
            "",
            "| input | marker set | pose model | ankle range (deg) | subtalar range | MTP range |",
            "|---|---|---|---|---|---|",
        ]
        for r in feet:
            a, s_, m = r["ankle_range"], r["subtalar_range"], r["mtp_range"]
            rows.append(
                f"| {r['label']} | {r['markerset']} | {r.get('pose_model', '-')} "
                f"| {a[0]:.0f} to {a[1]:.0f} | {s_[0]:.0f} to {s_[1]:.0f} "
                f"| {m[0]:.0f} to {m[1]:.0f} |"
            )
    compared = [r for r in results if "vs_truth" in r]
    if compared:
        rows += [
            "",
            "| input | marker set | frames | joint angle RMS difference from the ground truth's "
            "IK (deg): hip flexion / adduction / rotation, knee, elbow |",
            "|---|---|---|---|",
        ]
        for r in compared:
            d = r["vs_truth"]["rms_deg"]
            rows.append(
                f"| {r['label']} | {r['markerset']} | {r['vs_truth']['frames']} "
                f"| {d['hip_flexion']:.1f} / {d['hip_adduction']:.1f} / {d['hip_rotation']:.1f}, "
                f"{d['knee_angle']:.1f}, {d['elbow_flex']:.1f} |"
            )
    return "\n".join(rows)


def solve_all(picked: dict, truth, args: argparse.Namespace, height: float, python: Path):
    """Pose2Sim scaling + IK of every input (and of the ground truth, when given) with each
    marker set of ``args.markerset``; each input's angles are compared with the truth's."""
    sets = MARKERSETS if args.markerset == "both" else (args.markerset,)
    results = []
    for markerset in sets:
        ref = None
        if truth is not None:
            log.info("Shelf ground truth, %s marker set: Pose2Sim scaling + IK ...", markerset)
            ref = run_one("truth", truth, markerset, args, height, python, truth=True)
            results.append(ref)
        for label, one in picked.items():
            log.info("%s, %s marker set: Pose2Sim scaling + IK ...", label, markerset)
            r = run_one(label, one, markerset, args, height, python)
            if ref is not None:
                r["vs_truth"] = angle_errors(
                    args.out / f"{label}-{markerset}",
                    Path(r["trc"]).stem,
                    args.out / f"truth-{markerset}",
                    Path(ref["trc"]).stem,
                )
            results.append(r)
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", nargs="+", metavar="LABEL=NPZ", help="rmpl poses, first = reference")
    ap.add_argument("--out", type=Path, help="output folder")
    ap.add_argument("--person", type=int, default=None, help="person id in the first input")
    ap.add_argument("--height", type=float, default=None, help="m (default: estimated)")
    ap.add_argument("--mass", type=float, default=70.0, help="kg")
    ap.add_argument("--markerset", choices=(*MARKERSETS, "both"), default="both")
    ap.add_argument("--missing", choices=("gaps", "interpolate", "complete"), default="gaps")
    ap.add_argument("--augmenter", action="store_true", help="also try Pose2Sim's LSTM augmenter")
    ap.add_argument("--opensim-venv", type=Path, default=REPO / ".venv-opensim")
    ap.add_argument("--force", action="store_true", help="run finished inputs again")
    ap.add_argument("--shelf-gt", type=Path, help="Shelf folder: also IK its ground truth")
    ap.add_argument("--actor", type=int, default=0, help="Shelf actor id (0 = actor 1)")
    ap.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker is not None:
        worker(args.worker, args.height, args.mass, args.markerset, args.augmenter)
        return 0
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if not args.poses or args.out is None:
        ap.error("--poses and --out are required")
    python = args.opensim_venv / "bin" / "python"
    if not python.exists():
        ap.error(f"no OpenSim venv at {args.opensim_venv}: run scripts/setup_opensim.sh")
    inputs = {}
    for item in args.poses:
        label, _, path = item.partition("=")
        if not path or not Path(path).is_file():
            ap.error(f"--poses {item}: expected LABEL=path/to/poses.npz (an existing file)")
        inputs[label] = Path(path)
    args.out = args.out.resolve()  # the worker runs in the project folder
    args.out.mkdir(parents=True, exist_ok=True)
    picked = pick_people(inputs, args.person)
    first = next(iter(picked.values()))
    height, source = height_of(first, args.height)
    log.info("participant height %.3f m (%s), mass %.1f kg", height, source, args.mass)
    truth = None if args.shelf_gt is None else shelf_truth(args.shelf_gt, args.actor, first.fps)
    results = solve_all(picked, truth, args, height, python)
    summary = dict(
        command=" ".join(sys.argv),
        height=height,
        height_source=source,
        mass=args.mass,
        results=results,
    )
    with tempfile.NamedTemporaryFile("w", dir=args.out, delete=False, suffix=".part") as f:
        json.dump(summary, f, indent=1)
    os.replace(f.name, args.out / "results.json")
    print(f"participant height {height:.3f} m ({source}), mass {args.mass:.1f} kg\n")
    print(table(results))
    for r in results:
        if "augmenter" in r:
            print(f"\n{r['label']}-{r['markerset']}: marker augmenter: {r['augmenter']}")
    return 0


if __name__ == "__main__":
    if "--worker" in sys.argv:  # in the OpenSim venv, where rmpl is not installed
        raise SystemExit(main())
    from rmpl.benchmarks._common import run_main

    raise SystemExit(run_main(main))
