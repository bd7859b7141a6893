"""The run report: how well the 3D fits each view's 2D, per joint, camera and person.

:func:`build_report` takes a run's :class:`rmpl.io.poses.Poses3D` and its inputs and returns
a :class:`RunReport`: the poses with each person's estimated height and the per-view
status of the consistency check (:mod:`rmpl.pipeline.consistency`), and the tables that
``rmpl run`` writes as ``report.md`` (for people) and ``report.json`` (for programs), and
summarises in a few log lines (:func:`log_summary`).

What is measured (the report states the same):

- **Reprojection error**: the distance in pixels between a view's 2D keypoint of a person
  and the person's 3D joint projected into that view, over every measured joint (lifted or
  triangulated, not gap-filled) and every view with a 2D keypoint of that person (any
  confidence > 0). The same in millimetres: the pixel error back-projected at the joint's
  depth in that camera (``px * depth / focal length``), i.e. how far off the 3D joint is,
  sideways, as seen from that camera. Median and 90th percentile.
- **Views with 2D / used / excluded** (per joint, mean over its measured frames): the views
  with a 2D keypoint of the joint, the views the estimator used (``num_views``), and the
  difference (views left out by robust triangulation's view exclusion or a confidence
  threshold; the lifter uses every view).
- **Per camera**: how often the camera's 2D of a tracked person agrees or disagrees with
  the other views, how often it missed a person who was in its field of view, and the
  share of its keypoints the estimator left out.
- **Per person**: frames present, frames and joints whose gaps were filled by
  interpolation (flag INTERPOLATED), the estimated standing height
  (:func:`rmpl.anthropometry.estimate_height`), and the view check's verdict.
- **Identities**: how the tracker's fragments became one track per person
  (:mod:`rmpl.pipeline.identity`): per track its frames, fragments and height, and every
  merge (a duplicate, a fragment re-linked across a gap, one folded in by ``--people``)
  and drop (too short, a ghost) with its evidence; when the run says (``Poses3D.identity``).
- **Floor**: the floor plane the lifter was given (the user's or one estimated from the
  run, :func:`rmpl.pipeline.runner.run_with_floor`), or none; when the caller says.

Joint sets: the rows are the 3D's joints (``Poses3D.skeleton``, COCO-17 or HALPE-26). The
2D is placed into that joint set by name (:func:`rmpl.skeleton.embed`): a joint the 2D lacks
(HALPE-26's head top, neck, mid-hip and feet from a COCO-17 detector) has no 2D, so no
reprojection error and 0 views with 2D, and its row still gives the views the estimator
used.

Shape glossary: ``T`` frames, ``P`` people, ``V`` views, ``J`` joints.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.poses import JointSource, Poses3D, ViewStatus
from rmpl.pipeline.consistency import (
    MOVED_PX,
    MOVED_RATIO,
    Consistency,
    ConsistencyConfig,
    check_views,
    format_ranges,
    held_out_px,
    moved_cameras,
    person_2d,
)
from rmpl.skeleton import BY_COUNT, SKELETONS, embed, embed_scores

__all__ = ["RunReport", "build_report", "log_summary", "write_report"]

log = logging.getLogger(__name__)

_TAG = "rmpl.report"


@dataclass
class RunReport:
    """A run's diagnostics.

    Attributes:
        poses: the run's poses with ``heights`` and ``view_status`` (and ``membership``
            when it could be derived) filled in.
        consistency: the view check, or None when the 2D of each person is unknown.
        height_notes: per person, why its height is unknown ("" when known).
        people, cameras, joints: table rows (dicts of plain numbers and text).
        disagreements: rows of (person, camera, frames, ranges, median error).
        notes: sentences for the reader (what could not be measured and why).
        one_camera: with one camera, where depth came from and how uncertain it is
            (``statement``, ``uncertainty_50_mm_median``, ``uncertainty_50_mm_p90``); None
            with more cameras.
        floor: the floor the lifter was given (:func:`floor_entry`), or None when not
            recorded.
        identity: how the tracks were formed (:func:`identity_entry`), or None when the
            run does not say (one person, or poses read from a file).
    """

    poses: Poses3D
    consistency: Consistency | None
    height_notes: list[str]
    people: list[dict]
    cameras: list[dict]
    joints: list[dict]
    disagreements: list[dict]
    notes: list[str] = field(default_factory=list)
    one_camera: dict | None = None
    floor: dict | None = None
    identity: dict | None = None
    sync: dict | None = None  # the offsets applied to the 2D (rmpl run --sync)

    @property
    def exit_code(self) -> int:
        """0, or :data:`rmpl.pipeline.consistency.EXIT_VIEWS_DISAGREE` (3) when a person's
        views disagree in most of its frames."""
        return 0 if self.consistency is None else self.consistency.exit_code

    @property
    def failed(self) -> list[int]:
        """Ids of the people whose views disagree in most frames."""
        if self.consistency is None:
            return []
        return self.poses.person_ids[self.consistency.failed].tolist()

    def to_json(self) -> dict:
        cfg = self.consistency.config if self.consistency else ConsistencyConfig()
        return {
            "format": _TAG,
            "version": 1,
            "units": {"reprojection_px": "pixels", "reprojection_mm": "millimetres",
                      "height_m": "metres", "error_of_size": "fraction of the person's size"},
            "definitions": _DEFINITIONS,
            "check": {
                "threshold": cfg.threshold,
                "min_joints": cfg.min_joints,
                "most_frames": cfg.most_frames,
                "done": self.consistency is not None and bool(self.consistency.compared.any()),
            },
            "exit_code": self.exit_code,
            "failed_people": self.failed,
            "frames": {"count": self.poses.num_frames,
                       "first": int(self.poses.frames[0]) if self.poses.num_frames else None,
                       "last": int(self.poses.frames[-1]) if self.poses.num_frames else None},
            "fps": self.poses.fps,
            "cameras": self.cameras,
            "people": self.people,
            "joints": self.joints,
            "disagreements": self.disagreements,
            "notes": self.notes,
            "one_camera": self.one_camera,
            "floor": self.floor,
            "identity": self.identity,
            "sync": self.sync,
        }  # fmt: skip

    def to_markdown(self) -> str:
        return _markdown(self)


_DEFINITIONS = {
    "reprojection_error": "distance in pixels between a view's 2D keypoint of a person and the "
    "person's 3D joint projected into that view; measured joints only (not gap-filled), "
    "views with a 2D keypoint of the person only",
    "reprojection_mm": "the pixel error back-projected at the joint's depth in that camera "
    "(px x depth / focal length): how far off the 3D joint is, sideways, seen from the camera",
    "views_with_2d": "views with a 2D keypoint of the joint (mean over the joint's measured "
    "frames)",
    "views_used": "views the estimator used for the joint (mean)",
    "views_excluded": "views with 2D that the estimator left out (robust triangulation's view "
    "exclusion, a confidence threshold; the lifter uses every view) (mean)",
    "size": "the height in pixels the person would have standing upright at its distance "
    "from the camera (estimated height, else 1.70 m)",
    "error_of_size": "median over joints of a view's reprojection error against the 3D "
    "that the other, mutually agreeing, views triangulate, as a fraction of the size",
    "agrees": "error at most the threshold",
    "disagrees": "error above the threshold: the view shows another person, or a gross "
    "detection error (when no two views agree, all views disagree)",
    "left_right_swapped": "a disagreeing view whose 2D, with left and right exchanged, "
    "agrees (and is at least twice closer): the detector confused the person's sides in that "
    "view",
    "missed": "no 2D of the person in the view while its 3D lies inside the image",
    "out_of_view": "no 2D, and the person is outside the image",
    "unchecked": "2D present but fewer than 5 joints or no other view to compare with",
    "contested_frame": "at least 2 views compared and at least one of them disagrees: the "
    "3D of that frame is built from 2D that does not belong together",
    "failed_person": "contested in more than half of its compared frames: the 3D is most "
    "likely a blend of different people, or a camera's calibration is off (rmpl run exits "
    "with status 3)",
    "height": "standing height from the median shank, thigh and trunk lengths over the "
    "track and Drillis & Contini's proportions (they span 0.779 of the height); +-5%",
}


def _membership(poses: Poses3D, scores: np.ndarray) -> np.ndarray | None:
    """The poses' membership; with one 2D person per view, the only one where it has 2D."""
    if poses.membership is not None:
        return poses.membership
    if scores.shape[2] != 1:
        return None
    seen = (scores[:, :, 0] > 0).any(-1)  # (T, V)
    present = ~np.isnan(poses.points).all((-1, -2))  # (T, P)
    return np.where(seen[:, None] & present[..., None], 0, -1)


def _heights(poses: Poses3D, measured: np.ndarray) -> tuple[np.ndarray, list[str]]:
    from rmpl.anthropometry import estimate_height

    heights, notes = np.full(poses.num_people, np.nan), []
    for p in range(poses.num_people):
        pts = np.where(measured[:, p, :, None], poses.points[:, p], np.nan)
        try:
            heights[p] = estimate_height(pts, poses.skeleton)
            notes.append("")
        except InputError as e:
            notes.append(f"{e.expected}; got {e.got}")
    return heights, notes


def _stats(x: np.ndarray) -> tuple[float | None, float | None]:
    x = x[np.isfinite(x)]
    if not len(x):
        return None, None
    return round(float(np.median(x)), 2), round(float(np.percentile(x, 90)), 2)


#: :func:`build_report`'s ``floor`` when the caller does not say which floor the lifter read.
NOT_RECORDED = "not recorded"


def floor_entry(floor) -> dict | None:
    """The report's ``floor`` entry: ``given``, ``description``
    (:meth:`rmpl.geometry.floor.Floor.describe`, or "none"), and for a floor its ``normal``,
    ``height_m``, ``source`` and ``spread_m`` (the fitted points' spread, None when given).

    Args:
        floor: the :class:`rmpl.geometry.floor.Floor` the lifter was given, None (none), or
            :data:`NOT_RECORDED` (the entry is then None).
    """
    if isinstance(floor, str) and floor == NOT_RECORDED:
        return None
    if floor is None:
        return {"given": False, "description": "none"}
    spread = float(floor.spread)
    return {
        "given": True,
        "description": floor.describe(),
        "normal": [round(float(v), 6) for v in floor.normal],
        "height_m": round(float(floor.height), 6),
        "source": floor.source,
        "spread_m": round(spread, 4) if np.isfinite(spread) else None,
    }


def build_report(
    poses: Poses3D, inputs, config: ConsistencyConfig | None = None, floor=NOT_RECORDED
) -> RunReport:
    """Check the views and tabulate the diagnostics of a run.

    Args:
        poses: the run's result (:func:`rmpl.pipeline.runner.run`).
        inputs: the run's :class:`rmpl.pipeline.inputs.Inputs` (rig, 2D keypoints
            (T, V, N, J_2d, 2), scores (T, V, N, J_2d); their joint set is
            ``inputs.skeleton`` when it has one, else COCO-17 for 17 joints, HALPE-26 for
            26, the poses' own for as many joints as the poses).
        config: the view check's settings.
        floor: the floor the lifter was given (an :class:`rmpl.geometry.floor.Floor`, None
            for none, as :func:`rmpl.pipeline.runner.run_with_floor` returns it), or
            :data:`NOT_RECORDED`: the report then says nothing of the floor.

    Returns:
        :class:`RunReport`.
    """
    from rmpl.io.keypoints import drop_far_keypoints

    rig = inputs.rig
    kp, sc, _ = drop_far_keypoints(inputs.keypoints, inputs.scores, rig.sizes, view_axis=-4)
    pts = poses.points
    finite = ~np.isnan(pts).any(-1)  # (T, P, J)
    if poses.flags is not None:
        measured = np.isin(poses.flags, [JointSource.LIFTED, JointSource.TRIANGULATED])
    else:
        measured = finite
    heights, height_notes = _heights(poses, measured)
    membership = _membership(poses, sc)
    notes, consistency, kp2, sc2 = [], None, None, None
    if kp.shape[0] != poses.num_frames or kp.shape[1] != len(rig):
        notes.append("the 2D input does not match the poses' frames: no per-view figures")
    elif membership is None:
        notes.append("the poses do not say which 2D person each track used: no per-view figures")
    else:
        kp2, sc2 = _in_joints_of(poses, *person_2d(kp, sc, membership), inputs)
        mirror = SKELETONS[poses.skeleton].flip_permutation()
        consistency = check_views(pts, kp2, sc2, rig, heights, config, mirror)
        poses = dataclasses.replace(
            poses,
            membership=membership,
            view_status=consistency.status,
            camera_names=poses.camera_names or tuple(rig.names),
        )
    poses = dataclasses.replace(poses, heights=heights)
    people = _people(poses, measured, heights, height_notes, consistency)
    cameras, joints = [], []
    if consistency is not None:
        err_px, err_mm, with2d = _reprojection(pts, kp2, sc2, rig, measured)
        cameras = _cameras(poses, rig, consistency, err_px, err_mm, with2d, measured)
        joints = _joints(poses, err_px, err_mm, with2d, measured)
        for row, p in zip(people, range(poses.num_people), strict=True):
            row["reprojection_px_median"] = _stats(err_px[:, p])[0]
            row["reprojection_mm_median"] = _stats(err_mm[:, p])[0]
    disagreements = []
    if consistency is not None:
        for d in consistency.disagreements(poses.frames):
            disagreements.append(
                {
                    "person": int(poses.person_ids[d.person]),
                    "camera": poses.camera_names[d.view],
                    "frames": d.frames,
                    "ranges": [list(r) for r in d.ranges],
                    "left_right_swapped_frames": d.swapped,
                    "median_error_of_size": round(d.median_error, 3)
                    if np.isfinite(d.median_error)
                    else None,
                }
            )
    return RunReport(
        poses, consistency, height_notes, people, cameras, joints, disagreements, notes,
        _one_camera(poses) if len(rig) == 1 else None, floor_entry(floor),
        identity_entry(poses), getattr(inputs, "sync", None),
    )  # fmt: skip


def identity_entry(poses: Poses3D) -> dict | None:
    """The report's ``identity`` entry: the run's record (``Poses3D.identity``, from
    :meth:`rmpl.pipeline.identity.Identities.to_json`) with a row per track (``person``,
    ``frames``, ``fragments``, ``height_m``, ``merged``: the merges into it); None without a
    record."""
    rec = poses.identity
    if rec is None or len(rec.get("track_fragments", ())) != poses.num_people:
        return None
    heights = poses.heights if poses.heights is not None else np.full(poses.num_people, np.nan)
    rows = []
    for p, pid in enumerate(poses.person_ids.tolist()):
        parts = rec["track_fragments"][p]
        present = ~np.isnan(poses.points[:, p]).all((-1, -2))
        rows.append({
            "person": int(pid),
            "frames": int(present.sum()),
            "fragments": list(parts),
            "merged": sum(m["into"] in parts for m in rec["merges"]),
            "height_m": None if np.isnan(heights[p]) else round(float(heights[p]), 3),
        })  # fmt: skip
    return {**rec, "rows": rows}


ONE_CAMERA_STATEMENT = (
    "One camera: nothing triangulates the depth along each joint's ray. It comes from what the "
    "model learnt and from priors: where the floor is, how tall people are, that a person's "
    "size is constant and their distance changes smoothly (the run's log says which applied; "
    "without a floor or a body-size prior it is coarse). Sideways, seen from the camera, the "
    "joints are as good as the 2D; their distance from the camera is an estimate"
)


def _one_camera(poses: Poses3D) -> dict:
    """The one-camera statement and the spread of the per-joint depth-error radius."""
    r = poses.uncertainty
    r = r[np.isfinite(r)] * 1000 if r is not None else np.zeros(0)
    median = round(float(np.median(r)), 1) if r.size else None
    p90 = round(float(np.percentile(r, 90)), 1) if r.size else None
    return {
        "statement": ONE_CAMERA_STATEMENT,
        "uncertainty_50_mm_median": median,
        "uncertainty_50_mm_p90": p90,
    }


def _in_joints_of(poses: Poses3D, kp2: np.ndarray, sc2: np.ndarray, inputs):
    """Each person's 2D (T, P, V, J_2d, 2) and scores placed into the poses' joint set by
    name (joints the 2D lacks: NaN / 0)."""
    J2 = kp2.shape[-2]
    name = getattr(inputs, "skeleton", None)
    if name is None:
        name = poses.skeleton if J2 == len(poses.joint_names) else BY_COUNT.get(J2)
    if name == poses.skeleton:
        return kp2, sc2
    if name not in SKELETONS or SKELETONS[name].num_joints != J2:
        raise InputError(
            None, "keypoints", f"2D of a known joint set ({poses.skeleton}, coco17, halpe26)",
            f"{J2} joints",
        )  # fmt: skip
    return embed(kp2, name, poses.skeleton), embed_scores(sc2, name, poses.skeleton)


def _reprojection(pts, kp2, sc2, rig, measured):
    """Per (T, P, V, J): the pixel and millimetre errors of measured joints against the 2D
    (NaN elsewhere), and which views have a 2D keypoint."""
    proj = rig.project(pts)  # (T, P, V, J, 2)
    with2d = np.isfinite(kp2).all(-1) & (sc2 > 0)
    px = np.linalg.norm(proj - kp2, axis=-1)
    ok = with2d & measured[:, :, None, :] & np.isfinite(px)
    px = np.where(ok, px, np.nan)
    depth = np.einsum("vij,tpkj->tpvki", rig.R, pts)[..., 2] + rig.t[None, None, :, None, 2]
    f = 0.5 * (rig.K[:, 0, 0] + rig.K[:, 1, 1])[:, None]  # (V, 1)
    mm = px * depth / f * 1000.0
    return px, mm, with2d


def _people(poses, measured, heights, notes, consistency) -> list[dict]:
    rows = []
    flags = poses.flags
    for p, pid in enumerate(poses.person_ids.tolist()):
        present = ~np.isnan(poses.points[:, p]).all((-1, -2))
        filled = flags[:, p] == JointSource.INTERPOLATED if flags is not None else None
        row = {
            "person": int(pid),
            "frames": int(present.sum()),
            "first_frame": int(poses.frames[present][0]) if present.any() else None,
            "last_frame": int(poses.frames[present][-1]) if present.any() else None,
            "frames_measured": int(measured[:, p].any(-1).sum()),
            "frames_gap_filled": None if filled is None else int(filled.any(-1).sum()),
            "joints_gap_filled": None if filled is None else int(filled.sum()),
            "height_m": None if np.isnan(heights[p]) else round(float(heights[p]), 3),
            "height_note": notes[p],
        }
        if consistency is not None:
            dis = (consistency.status[:, p] == ViewStatus.DISAGREES).any(-1)
            row.update(
                frames_compared=int(consistency.compared[:, p].sum()),
                frames_with_disagreeing_view=int(dis.sum()),
                frames_contested=int(consistency.contested[:, p].sum()),
                failed=bool(consistency.failed[p]),
            )
        rows.append(row)
    return rows


def _cameras(poses, rig, consistency, err_px, err_mm, with2d, measured) -> list[dict]:
    rows = []
    st = consistency.status
    held_out = held_out_px(consistency)
    moved = moved_cameras(held_out)
    for v, name in enumerate(rig.names):
        count = {s: int((st[:, :, v] == s).sum()) for s in ViewStatus}
        in_view = sum(count[s] for s in ViewStatus if s not in (0, ViewStatus.OUT_OF_VIEW))
        keypoints = int((with2d[:, :, v] & measured).sum())
        excluded = (
            None
            if poses.views_excluded is None or not keypoints
            else round(100 * float(poses.views_excluded[:, :, v].sum()) / keypoints, 1)
        )
        rows.append(
            {
                "camera": name,
                "person_frames_in_view": in_view,
                "agrees": count[ViewStatus.AGREES],
                "disagrees": count[ViewStatus.DISAGREES],
                "missed": count[ViewStatus.MISSED],
                "unchecked": count[ViewStatus.UNCHECKED],
                "out_of_view": count[ViewStatus.OUT_OF_VIEW],
                "missed_percent": round(100 * count[ViewStatus.MISSED] / in_view, 1)
                if in_view
                else None,
                "disagrees_percent": round(100 * count[ViewStatus.DISAGREES] / in_view, 1)
                if in_view
                else None,
                "keypoints_excluded_percent": excluded,
                "reprojection_px_median": _stats(err_px[:, :, v])[0],
                "reprojection_mm_median": _stats(err_mm[:, :, v])[0],
                "held_out_px_median": None
                if not np.isfinite(held_out[v])
                else round(float(held_out[v]), 1),
                "moved_since_calibration": bool(moved[v]),
            }
        )
    return rows


def _joints(poses, err_px, err_mm, with2d, measured) -> list[dict]:
    rows = []
    n2d = with2d.sum(2)  # (T, P, J)
    used = poses.num_views if poses.num_views is not None else None
    for j, name in enumerate(poses.joint_names):
        m = measured[..., j]
        px, mm = _stats(err_px[..., j]), _stats(err_mm[..., j])
        row = {
            "joint": name,
            "measured": int(m.sum()),
            "reprojection_px_median": px[0],
            "reprojection_px_p90": px[1],
            "reprojection_mm_median": mm[0],
            "reprojection_mm_p90": mm[1],
            "views_with_2d": round(float(n2d[..., j][m].mean()), 2) if m.any() else None,
        }
        if used is not None:
            u = used[..., j][m]
            row["views_used"] = round(float(u.mean()), 2) if m.any() else None
            excl = np.clip(n2d[..., j][m] - u, 0, None)
            row["views_excluded"] = round(float(excl.mean()), 2) if m.any() else None
        if poses.uncertainty is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                r = np.nanmedian(np.where(m, poses.uncertainty[..., j], np.nan))
            row["predicted_error_radius_mm"] = None if np.isnan(r) else round(1000 * float(r), 1)
        rows.append(row)
    return rows


# --------------------------------------------------------------------------- text


def _cell(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return f"{x:g}"
    return str(x)


def _table(rows: list[dict], columns: list[tuple[str, str]]) -> list[str]:
    out = ["| " + " | ".join(h for _, h in columns) + " |"]
    out.append("|" + "|".join("---" for _ in columns) + "|")
    out += ["| " + " | ".join(_cell(r.get(k)) for k, _ in columns) + " |" for r in rows]
    return out


def verdict_lines(report: RunReport) -> list[str]:
    """The check's verdict as sentences: failures first, then every disagreeing view."""
    c = report.consistency
    if c is None:
        return ["The views were not checked: " + "; ".join(report.notes)]
    lines = []
    for p, pid in enumerate(report.poses.person_ids.tolist()):
        rows = [d for d in report.disagreements if d["person"] == pid]
        if not rows:
            continue
        dis = int((c.status[:, p] == ViewStatus.DISAGREES).any(-1).sum())
        views = "; ".join(
            f"{d['camera']} in {d['frames']} frames ({format_ranges(d['ranges'])})"
            + (
                f", left/right swapped in {d['left_right_swapped_frames']} of them"
                if d["left_right_swapped_frames"]
                else ""
            )
            for d in rows
        )
        head = (
            f"person {pid} FAILED the view check: in {dis} of its "
            f"{int(c.compared[:, p].sum())} compared frames a view disagrees with the others "
            "- its 3D is most likely a blend of different people"
            if c.failed[p]
            else f"person {pid}: a view disagrees with the others in {dis} of "
            f"{int(c.compared[:, p].sum())} compared frames"
        )
        lines.append(f"{head}: {views}")
    if not lines:
        n = int(c.compared.sum())
        lines.append(
            f"every view agrees with the others for every person ({n} person-frames compared)"
            if n
            else "not checked: no person was seen by enough views to compare them (one "
            "camera, or nobody in two or more views)"
        )
    return lines


def _markdown(r: RunReport) -> str:
    md = _md_summary(r) + _md_people(r) + _md_disagreements(r)
    md += _md_cameras(r) + _md_joints(r) + _md_definitions(r)
    return "\n".join(md) + "\n"


def _md_summary(r: RunReport) -> list[str]:
    """report.md's title, floor, verdict and the one-camera statement."""
    p = r.poses
    frames = f"{p.frames[0]}-{p.frames[-1]}" if p.num_frames else "none"
    fps = f"{p.fps:g} frames/s" if p.fps else "frame rate unknown"
    md = [
        "# rmpl run report",
        "",
        f"{p.num_frames} frames ({frames}, {fps}), {p.num_people} "
        f"{'person' if p.num_people == 1 else 'people'}, "
        f"{len(p.camera_names or ())} cameras ({', '.join(p.camera_names or ())}).",
        "",
    ]
    if r.floor is not None:
        md += [f"Floor: {r.floor['description']}.", ""]
    if r.sync is not None:
        offs = ", ".join(f"{n} {c['offset_frames']} frames ({c['offset_seconds']:+.3f} s)"
                         for n, c in r.sync["cameras"].items())  # fmt: skip
        md += [f"Synchronisation ({r.sync['source']}, {r.sync['method']}): {offs}.", ""]
    md += [
        "## Verdict",
        "",
    ]
    if r.failed:
        md += [
            f"**WARNING: the views disagree on person(s) {', '.join(map(str, r.failed))} in most "
            "frames. Their 3D is most likely a blend of different people; do not use it. "
            f"`rmpl run` exits with status {r.exit_code}.** Check the detections of the "
            "cameras listed below (a detector that finds one person per image picks different "
            "people in different cameras when several are filmed), and their calibration.",
            "",
        ]
    md += [f"- {line}" for line in verdict_lines(r)] + [""]
    if r.one_camera is not None:
        oc = r.one_camera
        md += ["## One camera: depth from priors", "", oc["statement"] + "."]
        if oc["uncertainty_50_mm_median"] is not None:
            md += [
                "",
                f"How uncertain: half of the joints' depth errors are expected within "
                f"{oc['uncertainty_50_mm_median']:.0f} mm (median over joints and frames; 90th "
                f"percentile {oc['uncertainty_50_mm_p90']:.0f} mm), per joint in "
                "poses.json/npz `uncertainty`. It leaves out the lifter's error in the "
                "body's shape.",
            ]
        md += [""]
    return md


def _md_people(r: RunReport) -> list[str]:
    md = ["## People", ""]
    md += _table(
        r.people,
        [
            ("person", "person"),
            ("frames", "frames present"),
            ("first_frame", "first"),
            ("last_frame", "last"),
            ("frames_gap_filled", "frames with gaps filled"),
            ("joints_gap_filled", "joints gap-filled"),
            ("height_m", "height (m)"),
            ("reprojection_px_median", "reproj. error median (px)"),
            ("reprojection_mm_median", "reproj. error median (mm)"),
            ("frames_with_disagreeing_view", "frames with a disagreeing view"),
            ("failed", "failed view check"),
        ],
    )
    unknown = [f"person {row['person']}: {row['height_note']}" for row in r.people
               if row["height_note"]]  # fmt: skip
    if unknown:
        md += ["", "Height unknown for " + "; ".join(unknown) + "."]
    if r.identity is not None:
        md += ["", "## Identities", ""] + _identity_lines(r.identity)
    return md


def _md_disagreements(r: RunReport) -> list[str]:
    md = ["", "## View disagreements", ""]
    if r.disagreements:
        md += _table(
            [{**d, "ranges_text": format_ranges(d["ranges"], limit=20)} for d in r.disagreements],
            [
                ("person", "person"),
                ("camera", "camera"),
                ("frames", "frames"),
                ("ranges_text", "frame ranges"),
                ("median_error_of_size", "median error (fraction of size)"),
                ("left_right_swapped_frames", "of which left/right swapped"),
            ],
        )
    else:
        md += ["None." if r.consistency is not None else "Not checked."]
    return md


def _md_cameras(r: RunReport) -> list[str]:
    md = []
    if r.cameras:
        md += ["", "## Cameras", "", "Counts are person-frames (one person in one frame).", ""]
        md += _table(
            r.cameras,
            [
                ("camera", "camera"),
                ("person_frames_in_view", "in view"),
                ("agrees", "agrees"),
                ("disagrees", "disagrees"),
                ("missed", "missed"),
                ("missed_percent", "missed (%)"),
                ("unchecked", "unchecked"),
                ("out_of_view", "out of view"),
                ("keypoints_excluded_percent", "keypoints excluded (%)"),
                ("reprojection_px_median", "reproj. error median (px)"),
                ("reprojection_mm_median", "reproj. error median (mm)"),
                ("held_out_px_median", "held-out error median (px)"),
            ],
        )
        moved = [c["camera"] for c in r.cameras if c.get("moved_since_calibration")]
        rule = f"{MOVED_PX:g} px and {MOVED_RATIO:g} times the others'"
        md += [
            "",
            "Calibration: "
            + (
                f"{', '.join(moved)} may have moved since calibration (its held-out error, "
                f"its 2D against the people placed by the other cameras, is over {rule}): "
                "check it with `rmpl calibrate --check`."
                if moved
                else "no camera appears to have moved since calibration (no held-out error "
                f"over {rule})."
            ),
        ]
    return md


def _md_joints(r: RunReport) -> list[str]:
    md = []
    if r.joints:
        md += ["", "## Joints", "", "Over every person, measured frame and view with 2D.", ""]
        cols = [
            ("joint", "joint"),
            ("measured", "measured joint-frames"),
            ("reprojection_px_median", "reproj. median (px)"),
            ("reprojection_px_p90", "reproj. 90th pct (px)"),
            ("reprojection_mm_median", "reproj. median (mm)"),
            ("reprojection_mm_p90", "reproj. 90th pct (mm)"),
            ("views_with_2d", "views with 2D"),
            ("views_used", "views used"),
            ("views_excluded", "views excluded"),
        ]
        if r.joints and "predicted_error_radius_mm" in r.joints[0]:
            cols.append(("predicted_error_radius_mm", "predicted 50% error radius (mm)"))
        md += _table(r.joints, cols)
    return md


def _md_definitions(r: RunReport) -> list[str]:
    cfg = r.consistency.config if r.consistency else ConsistencyConfig()
    md = ["", "## Definitions", ""]
    md += [f"- **{k.replace('_', ' ')}**: {v}." for k, v in _DEFINITIONS.items()]
    md += [
        f"- **threshold**: a view disagrees above {cfg.threshold:g} of the person's size "
        f"({cfg.threshold * 170:.0f} cm at the person's distance for a 1.70 m person).",
        "",
        "Units: pixels (px) in the camera images, millimetres (mm) and metres (m) in the "
        "world. Frame numbers are the input's.",
    ]
    if r.notes:
        md += ["", "## Notes", ""] + [f"- {n}" for n in r.notes]
    return md


_MERGE_TEXT = {
    "duplicate": "the same person seen twice (torso centres {distance_m} m apart)",
    "relinked": "re-linked across a gap of {gap_frames} frames ({distance_m} m, body "
    "difference {body_difference})",
    "people": "folded in by --people (gap {gap_frames} frames, body difference {body_difference})",
    "people-body": "folded in by --people (between its frames; body difference {body_difference})",
}


class _Blank(dict):
    """Fields a merge does not have read as "-"."""

    def __missing__(self, key: str) -> str:
        return "-"


def _identity_lines(rec: dict) -> list[str]:
    """The report's identity table, then one line per merge and drop."""
    md = [
        f"{rec['tracks']} tracks from the tracker's {rec['fragments']} fragments: "
        f"{len(rec['merges'])} merged, {len(rec['drops'])} dropped "
        "(rules: `rmpl.pipeline.identity`).",
        "",
    ]
    rows = [{**row, "fragments_text": ", ".join(map(str, row["fragments"]))}
            for row in rec["rows"]]  # fmt: skip
    md += _table(
        rows,
        [("person", "person"), ("frames", "frames"), ("fragments_text", "tracker fragments"),
         ("merged", "merges"), ("height_m", "height (m)")],
    )  # fmt: skip
    if rec["merges"] or rec["drops"]:
        md.append("")
    owner = {f: row["person"] for row in rec["rows"] for f in row["fragments"]}
    for m in rec["merges"]:
        kind = m["kind"] if m["kind"] != "people" or "gap_frames" in m else "people-body"
        text = _MERGE_TEXT.get(kind, kind).format_map(_Blank({k: _cell(v) for k, v in m.items()}))
        md.append(f"- fragment {m['fragment']} -> person {owner.get(m['into'], '-')}: {text}")
    for d in rec["drops"]:
        md.append(f"- fragment {d['fragment']} dropped ({d['kind']}, {d['frames']} "
                  f"frame{'' if d['frames'] == 1 else 's'}): "
                  f"{d['reason']}")  # fmt: skip
    return md


def write_report(report: RunReport, folder: Path) -> list[Path]:
    """``report.md`` and ``report.json`` in ``folder`` (a staging folder: the caller commits)."""
    folder = Path(folder)
    md, js = folder / "report.md", folder / "report.json"
    md.write_text(report.to_markdown(), encoding="utf-8")
    js.write_text(json.dumps(report.to_json(), indent=1, allow_nan=False), encoding="utf-8")
    return [md, js]


def log_summary(report: RunReport, out: Path | None = None) -> None:
    """A few INFO lines; every disagreeing view at WARNING; a banner for a failed person."""
    rows = report.joints
    if rows:
        allpx = [row["reprojection_px_median"] for row in rows if row["reprojection_px_median"]]
        allmm = [row["reprojection_mm_median"] for row in rows if row["reprojection_mm_median"]]
        if allpx:
            log.info(
                "report: reprojection error, median over joints of the per-joint medians: "
                "%.1f px (%.0f mm)", float(np.median(allpx)), float(np.median(allmm)),
            )  # fmt: skip
    people = [
        f"person {row['person']}: {row['frames']} frames, "
        f"{row['frames_gap_filled'] if row['frames_gap_filled'] is not None else '-'} gap-filled, "
        + (f"height {row['height_m']:.2f} m" if row["height_m"] else "height unknown")
        for row in report.people[:6]
    ]
    more = f" (+{len(report.people) - 6} more)" if len(report.people) > 6 else ""
    if people:
        log.info("report: %s%s", "; ".join(people), more)
    c = report.consistency
    if c is None:
        log.info("report: views not checked (%s)", "; ".join(report.notes))
    else:
        lines = verdict_lines(report)
        if report.disagreements:
            for line in lines:
                log.warning("WARNING: view check: %s", line)
        else:
            log.info("view check: %s", lines[0])
    if report.failed:
        bar = "!" * 78
        log.warning(bar)
        log.warning(
            "WARNING: THE VIEWS DISAGREE on person(s) %s in most frames: the 3D is most likely "
            "a blend of different people (a detector that finds one person per image picked "
            "different "
            "people in different cameras?) or a camera's calibration is off. Do not use it; "
            "see %s. Exit status %d.",
            ", ".join(map(str, report.failed)),
            (out / "report.md") if out else "report.md",
            report.exit_code,
        )
        log.warning(bar)
