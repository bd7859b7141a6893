"""Do tracks keep a person? ``rmpl run``'s identities on Shelf and on recordings.

``shelf``: runs ``rmpl run --fps 25`` on a Shelf folder (or reads a finished run's
``poses.npz`` with ``--poses``), matches the tracks to the ground truth in every frame
(Hungarian on the mean distance of the 12 limb joints, 0.5 m gate, as ``rmpl evaluate``
does), and gives per annotated actor the share of the frames it is annotated in that its
longest track holds, and the tracks it was split into; then the number of tracks, and the
run's identity record (merges, drops).

``recording``: runs ``rmpl run`` on any calibration + 2D (or reads ``--poses``) and gives
the tracks, each track's frames and share of the recording, and its largest torso step
between consecutive frames (a swap between two people shows as a jump of their distance).

    python -m rmpl.benchmarks.identity shelf --root SHELF_DIR --out OUT [--poses P.npz]
    python -m rmpl.benchmarks.identity recording --calib CALIB --keypoints KP --out OUT \\
        [--fps 60] [--skeleton body25b] [--people 2] [--poses P.npz]

Writes ``OUT/identity.json`` and prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

_SHELF_TO_COCO = [16, 14, 12, 11, 13, 15, 10, 8, 6, 5, 7, 9]  # Shelf joints 0-11 in COCO-17
_GATE = 0.5


def _run(argv: list[str], out: Path) -> Path:
    from rmpl.cli import main

    code = main(["run", *argv, "--no-pictures", "--formats", "npz", "--pose2sim", "off",
                 "--out", str(out)])  # fmt: skip
    if code not in (0, 3):
        raise SystemExit(code)
    return out / "poses.npz"


def actor_tracks(points: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(T, P) the ground-truth actor each track is matched to per frame, -1 where none.

    Args:
        points: (T, P, J, 3) the run's tracks (first 17 joints COCO-17's).
        gt: (T, A, 15, 3) Shelf ground truth, NaN where an actor is absent.
    """
    from scipy.optimize import linear_sum_assignment

    T, P = points.shape[:2]
    own = np.full((T, P), -1)
    limbs = points[:, :, _SHELF_TO_COCO]  # (T, P, 12, 3)
    for t in range(T):
        actors = np.flatnonzero(np.isfinite(gt[t, :, :12]).all((-1, -2)))
        tracks = np.flatnonzero(np.isfinite(limbs[t]).all(-1).any(-1))
        if not len(actors) or not len(tracks):
            continue
        d = np.linalg.norm(gt[t][actors][:, None, :12] - limbs[t][tracks][None], axis=-1)
        with np.errstate(invalid="ignore"):
            cost = np.nanmean(np.where(np.isfinite(d), d, np.nan), axis=-1)  # (A, P)
        cost = np.where(np.isfinite(cost), cost, 1e9)
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows, cols, strict=True):
            if cost[r, c] <= _GATE:
                own[t, tracks[c]] = actors[r]
    return own


def shelf_table(points: np.ndarray, gt: np.ndarray) -> dict:
    """Per annotated actor: annotated frames, the longest track's share, the tracks."""
    own = actor_tracks(points, gt)
    rows = []
    for a in range(gt.shape[1]):
        annotated = np.isfinite(gt[:, a, :12]).all((-1, -2))
        if not annotated.any():
            continue
        held = (own[annotated] == a).sum(0)  # (P,)
        rows.append({
            "actor": a + 1,  # the customary numbering
            "annotated_frames": int(annotated.sum()),
            "longest_track_share": round(float(held.max() / annotated.sum()), 4),
            "tracks": int((held > 0).sum()),
        })  # fmt: skip
    present = np.isfinite(points).all(-1).any(-1)
    return {"tracks": int(points.shape[1]), "frames_per_track": present.sum(0).tolist(),
            "actors": rows}  # fmt: skip


def recording_table(points: np.ndarray, fps: float | None) -> dict:
    """Per track: frames, share of the recording, largest torso step (m) between frames."""
    import warnings

    T = len(points)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # frames without the torso: NaN
        torso = np.nanmean(points[:, :, [5, 6, 11, 12]], axis=2)
    rows = []
    for p in range(points.shape[1]):
        present = np.isfinite(points[:, p]).all(-1).any(-1)
        steps = np.linalg.norm(np.diff(torso[:, p], axis=0), axis=-1)
        steps = steps[np.isfinite(steps)]
        rows.append({
            "track": p,
            "frames": int(present.sum()),
            "share": round(float(present.mean()), 4),
            "largest_torso_step_m": round(float(steps.max()), 3) if len(steps) else None,
        })  # fmt: skip
    return {"frames": T, "fps": fps, "tracks": len(rows), "rows": rows}


def _markdown(result: dict) -> str:
    lines = [f"tracks: {result['tracks']}", ""]
    if "actors" in result:
        lines += [
            "| actor | annotated frames | longest track's share | tracks |",
            "|---|---:|---:|---:|",
        ]
        lines += [f"| {r['actor']} | {r['annotated_frames']} | "
                  f"{100 * r['longest_track_share']:.1f}% | {r['tracks']} |"
                  for r in result["actors"]]  # fmt: skip
    else:
        lines += ["| track | frames | share | largest torso step (m) |", "|---|---:|---:|---:|"]
        lines += [f"| {r['track']} | {r['frames']} | {100 * r['share']:.1f}% | "
                  f"{r['largest_torso_step_m']} |" for r in result["rows"]]  # fmt: skip
    ident = result.get("identity")
    if ident:
        lines += ["", f"identity: {ident['tracks']} tracks from {ident['fragments']} fragments, "
                  f"{len(ident['merges'])} merged ({_kinds(ident['merges'])}), "
                  f"{len(ident['drops'])} dropped ({_kinds(ident['drops'])})"]  # fmt: skip
    return "\n".join(lines)


def _kinds(items: list[dict]) -> str:
    kinds = [i["kind"] for i in items]
    return ", ".join(f"{k} {kinds.count(k)}" for k in sorted(set(kinds))) or "none"


def _identity_of(run_dir: Path) -> dict | None:
    report = run_dir / "report.json"
    if not report.is_file():
        return None
    return json.loads(report.read_text()).get("identity")


def main(argv: list[str] | None = None) -> int:
    from rmpl.io.poses import load_poses

    parser = argparse.ArgumentParser(prog="python -m rmpl.benchmarks.identity",
                                     description=__doc__.split("\n\n")[0])  # fmt: skip
    parser.add_argument("kind", choices=["shelf", "recording"])
    parser.add_argument("--out", required=True)
    parser.add_argument("--poses", default=None, help="a finished run's poses.npz (no run)")
    parser.add_argument("--root", help="shelf: the Shelf folder")
    parser.add_argument("--calib", help="recording: the calibration")
    parser.add_argument("--keypoints", nargs="+", help="recording: the 2D")
    parser.add_argument("--fps", default=None, help="recording: frame rate")
    parser.add_argument("--skeleton", default=None, help="recording: rmpl run --skeleton")
    parser.add_argument("--people", default=None, help="rmpl run --people")
    args = parser.parse_args(argv)
    out = Path(args.out)
    extra = ["--people", args.people] if args.people else []
    if args.kind == "shelf":
        from rmpl.data.shelf import load_shelf

        if not args.root:
            parser.error("shelf needs --root")
        root = Path(args.root)
        run = ["--calib", str(root / "calibration.json"), "--keypoints", str(root), "--fps", "25"]
        path = Path(args.poses) if args.poses else _run(run + extra, out / "run")
        poses = load_poses(path)
        result = shelf_table(poses.points, load_shelf(root).gt)
    else:
        if not (args.calib and args.keypoints) and not args.poses:
            parser.error("recording needs --calib and --keypoints, or --poses")
        run = ["--calib", args.calib, "--keypoints", *(args.keypoints or [])]
        run += ["--fps", args.fps] if args.fps else []
        run += ["--skeleton", args.skeleton] if args.skeleton else []
        path = Path(args.poses) if args.poses else _run(run + extra, out / "run")
        poses = load_poses(path)
        result = recording_table(poses.points, poses.fps)
    result["identity"] = _identity_of(path.parent)
    out.mkdir(parents=True, exist_ok=True)
    (out / "identity.json").write_text(json.dumps(result, indent=1), encoding="utf-8")
    print(_markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
