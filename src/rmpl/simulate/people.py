"""The people of a simulated capture: their bodies, their motion and their paths.

Each person is an anny body of random phenotype (:func:`rmpl.synth.body.sample_phenotypes`)
moving with real motion capture from the package's motion library
(:mod:`rmpl.simulate.motion`: walking, running, bending; turning is walking in pieces of at
most 2 s, each turned towards a new heading). A person's track is a
chain of pieces of motion: each piece is one stretch of a clip, turned to head from where
the person stands towards a point on the edge of the walking area and cut where its path
would leave it; the next piece starts there and the two are blended over
:data:`BLEND_SECONDS` (a quick turn), so a person walks back and forth as people do in a
lab. Among several candidate headings, the one that keeps the person farthest from the
others is taken (people pass each other, they do not walk through each other, as far as
the draws allow). The body's hips follow the clip's own path scaled by the ratio of leg
lengths (shorter legs take shorter steps), and each piece stands on the floor (z = 0).

A bystander stands still at the edge of the area, facing its centre, in a standing frame
of a walking clip.

Everything is sampled on the motion library's grid (:data:`RATE` samples a second);
:func:`at_times` interpolates linearly between samples for each camera's instants.

Shape glossary: ``S`` samples, ``P`` people, ``N`` vertices, ``J`` joints (HALPE-26).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

__all__ = [
    "BLEND_SECONDS",
    "PersonPlan",
    "Piece",
    "at_times",
    "plan_people",
    "pose_people",
]

#: Seconds over which two pieces of one person's motion are blended.
BLEND_SECONDS = 0.4
#: Shortest piece, seconds (a piece is cut where it would leave the walking area).
MIN_PIECE = 1.0
#: Longest piece, seconds.
MAX_PIECE = 6.0
#: Candidate headings tried per piece.
TRIES = 12
#: Least distance between a new person's start and the others', metres.
START_GAP = 1.0


@dataclass
class Piece:
    """One stretch of a clip in a person's track.

    Attributes:
        segment: the motion bank's segment. rows: its bank rows, one per sample (n,).
        start: the first sample of the track it covers.
        yaw: radians about +z. origin: (2,) where the hips start on the floor, metres.
    """

    segment: int
    rows: np.ndarray
    start: int
    yaw: float
    origin: np.ndarray


@dataclass
class PersonPlan:
    """A person: identity, body, what they do and the pieces of their track."""

    id: int
    phenotype: np.ndarray
    kind: str
    bystander: bool = False
    pieces: list[Piece] = field(default_factory=list)

    def to_json(self, bank) -> dict:
        clips = [str(bank.clips[bank.clip_index[p.segment]]) for p in self.pieces]
        return {
            "id": self.id,
            "bystander": self.bystander,
            "motion": self.kind,
            "phenotype": [round(float(x), 4) for x in self.phenotype],
            "clips": sorted(set(clips)),
        }


def _rz(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _hips(bank, rows: np.ndarray) -> np.ndarray:
    """The clip's mid-hip on the floor plane, relative to its first row, (n, 2) metres."""
    h = bank.joints[rows][:, 11:13, :2].astype(float).mean(axis=1)
    return h - h[:1]


def _heading(path: np.ndarray) -> float | None:
    """Direction of a path's net displacement, radians; None when it hardly moves."""
    d = path[-1] - path[0]
    return float(np.arctan2(d[1], d[0])) if np.linalg.norm(d) > 0.5 else None


def _piece_seconds(kind: str) -> float:
    """Longest piece of a kind: turning is walking in pieces of at most 2 s."""
    return {"walk": MAX_PIECE, "turn": 2.0}.get(kind, MAX_PIECE / 2)


def _clip_kind(kind: str) -> str:
    """The library's kind a person's activity plays: turning is made of walking."""
    return "walk" if kind == "turn" else kind


def _place(path, pos, area, others, start, rng) -> tuple[float, int, float]:
    """A heading for a piece's path starting at ``pos``: (yaw, samples kept, score)."""
    best = (0.0, len(path), -np.inf)
    own = _heading(path)
    for _ in range(TRIES):
        target = rng.uniform(-np.pi, np.pi)
        aim = area * np.array([np.cos(target), np.sin(target)]) - pos
        yaw = float(np.arctan2(aim[1], aim[0]) - own) if own is not None else target
        xy = pos + path @ _rz(yaw).T
        out = np.flatnonzero(np.linalg.norm(xy, axis=1) > area)
        keep = int(out[0]) if len(out) else len(xy)
        keep = max(keep, 2)
        score = keep / len(xy)
        if others is not None:
            o = others[start : start + keep]  # (k, P', 2)
            if o.size:
                gap = np.nanmin(np.linalg.norm(o - xy[: len(o), None], axis=-1), initial=9.0)
                score += min(gap, 1.5)
        if score > best[2]:
            best = (yaw, keep, score)
    return best


def _plan_track(person: PersonPlan, bank, kinds, samples, area, scale, others, rng) -> np.ndarray:
    """Fill ``person.pieces``; returns the planned hips on the floor, (S, 2)."""
    from rmpl.simulate.motion import pick_segment

    rate = float(bank.fps[0])
    blend = int(round(BLEND_SECONDS * rate))
    min_len = int(MIN_PIECE * rate)
    track = np.full((samples, 2), np.nan)
    pos = _start(area, others, rng)
    clip_kind = _clip_kind(person.kind)
    longest = (bank.length[np.asarray(kinds) == clip_kind].max() - 1) / rate  # no ping-pong
    s = 0
    while s < samples - 1:
        want = min((samples - s + blend) / rate, _piece_seconds(person.kind), longest)
        seg, rows = pick_segment(bank, kinds, clip_kind, want, rng)
        path = _hips(bank, rows) * scale
        yaw, keep, _ = _place(path, pos, area, others, s, rng)
        keep = min(max(keep, min(min_len, len(rows))), samples - s)
        rows = rows[:keep]
        person.pieces.append(Piece(seg, rows, s, yaw, pos.copy()))
        xy = pos + path[:keep] @ _rz(yaw).T
        track[s : s + keep] = xy
        if s + keep >= samples:
            break
        nxt = max(keep - blend, 1)
        pos = xy[nxt]
        s += nxt
    return track


def _start(area: float, others, rng) -> np.ndarray:
    for _ in range(50):
        pos = rng.uniform(-area, area, 2) * 0.7
        if others is None or not np.isfinite(others[0]).any():
            return pos
        if np.nanmin(np.linalg.norm(others[0] - pos, axis=-1)) > START_GAP:
            return pos
    return pos


def plan_people(
    bank,
    kinds: np.ndarray,
    activities: list[str],
    bystander: bool,
    samples: int,
    area: float,
    leg_lengths: np.ndarray,
    phenotypes: np.ndarray,
    rng: np.random.Generator,
) -> list[PersonPlan]:
    """Every person's pieces: ``len(activities)`` moving people (person i does
    ``activities[i]``), then the bystander if asked for.

    Args:
        bank, kinds: the motion library (:func:`rmpl.simulate.motion.load_motion_library`).
        samples: S, on the bank's grid. area: radius of the walking area, metres.
        leg_lengths: each person's leg length, metres (P,), for the steps' scale.
        phenotypes: (P, 6), the bystander's last.
    """
    plans, tracks = [], []
    mocap_leg = _mocap_leg(bank)
    for i, kind in enumerate(activities):
        person = PersonPlan(i, phenotypes[i], kind)
        others = np.stack(tracks, axis=1) if tracks else None
        tracks.append(
            _plan_track(person, bank, kinds, samples, area, leg_lengths[i] / mocap_leg, others, rng)
        )
        plans.append(person)
    if bystander:
        i = len(activities)
        person = PersonPlan(i, phenotypes[i], "stand", bystander=True)
        row = _standing_row(bank, kinds)
        seg = int(np.searchsorted(bank.start, row, side="right") - 1)
        angle = rng.uniform(-np.pi, np.pi)
        pos = (area + 0.3) * np.array([np.cos(angle), np.sin(angle)])
        person.pieces.append(Piece(seg, np.full(samples, row), 0, angle + np.pi, pos))
        plans.append(person)
    return plans


def _mocap_leg(bank) -> float:
    from rmpl.anthropometry import leg_length

    return leg_length(bank.joints[:: max(len(bank.joints) // 500, 1)].astype(float))


def _standing_row(bank, kinds) -> int:
    """A bank row of a walking clip where the ankles are closest together (standing)."""
    seg = np.flatnonzero(np.asarray(kinds) == "walk")
    seg = seg if len(seg) else np.arange(len(bank))
    rows = np.concatenate(
        [np.arange(a, a + n) for a, n in zip(bank.start[seg], bank.length[seg], strict=True)]
    )
    j = bank.joints[rows].astype(float)
    apart = np.linalg.norm(j[:, 15, :2] - j[:, 16, :2], axis=-1)
    return int(rows[np.argmin(apart)])


def _pose_piece(body, bank, rows: np.ndarray, phen: np.ndarray, chunk: int = 48):
    """Posed vertices (n, N, 3) and HALPE-26 joints (n, 26, 3) of one piece in anny's frame,
    the hips following the clip's path (not yet turned or placed)."""
    from rmpl.anthropometry import leg_length
    from rmpl.synth.generate.sequences import _sequence_pose

    unique, inverse = np.unique(rows, return_inverse=True)
    seg = int(np.searchsorted(bank.start, unique[0], side="right") - 1)
    worker = SimpleNamespace(body=body, motion=bank, cfg=SimpleNamespace(perturb_deg=0.0))
    verts, joints = [], []
    for a in range(0, len(unique), chunk):
        part = unique[a : a + chunk]
        pose = _sequence_pose(worker, seg, part, phen, False, np.random.default_rng(0))
        out = body(pose, np.repeat(phen[None], len(part), axis=0))
        verts.append(out.vertices.astype(np.float32))
        joints.append(out.keypoints.astype(np.float32))
    verts, joints = np.concatenate(verts)[inverse], np.concatenate(joints)[inverse]
    mocap = bank.joints[rows].astype(float)
    scale = leg_length(joints[:, :17].astype(float)) / max(leg_length(mocap), 1e-6)
    path = mocap[:, 11:13].mean(axis=1)
    path = scale * (path - np.r_[path[0, :2], 0.0])
    shift = (path - joints[:, 11:13].mean(axis=1)).astype(np.float32)
    verts, joints = verts + shift[:, None], joints + shift[:, None]
    lift = -verts[..., 2].min()
    verts[..., 2] += lift
    joints[..., 2] += lift
    return verts, joints


def _facing(joints: np.ndarray) -> float:
    """The direction a body faces on the floor (radians), from its hips: (J, 3)."""
    left, right = joints[11, :2], joints[12, :2]
    d = left - right  # to the body's left
    return float(np.arctan2(d[1], d[0]) - np.pi / 2)


def pose_people(plans: list[PersonPlan], body, bank, samples: int, progress=None):
    """Every person at every sample: vertices (S, P, N, 3) float32 and HALPE-26 joints
    (S, P, 26, 3) float32, world metres; pieces of one person blended over
    :data:`BLEND_SECONDS`."""
    rate = float(bank.fps[0])
    blend = int(round(BLEND_SECONDS * rate))
    P, N = len(plans), body.num_vertices
    verts = np.zeros((samples, P, N, 3), np.float32)
    joints = np.zeros((samples, P, 26, 3), np.float32)
    for p, person in enumerate(plans):
        for k, piece in enumerate(person.pieces):
            v, j = _pose_piece(
                body, bank, piece.rows[:1] if person.bystander else piece.rows, person.phenotype
            )
            yaw = piece.yaw
            if person.bystander:
                yaw = piece.yaw - _facing(j[0])
            R = np.eye(3)
            R[:2, :2] = _rz(yaw)
            move = np.r_[piece.origin, 0.0].astype(np.float32)
            v = v @ R.T.astype(np.float32) + move
            j = j @ R.T.astype(np.float32) + move
            n = len(piece.rows)
            if person.bystander:
                v, j = np.broadcast_to(v, (n, *v.shape[1:])), np.broadcast_to(j, (n, *j.shape[1:]))
            a, b = piece.start, min(piece.start + n, samples)
            w = np.ones(b - a, np.float32)
            if k > 0:
                m = min(blend, b - a)
                x = (np.arange(m) + 1) / (m + 1)
                w[:m] = x * x * (3 - 2 * x)  # smoothstep
            w4 = w[:, None, None]
            verts[a:b, p] = (1 - w4) * verts[a:b, p] + w4 * v[: b - a]
            joints[a:b, p] = (1 - w4) * joints[a:b, p] + w4 * j[: b - a]
            if progress is not None:
                progress.update(1)
    return verts, joints


def at_times(values: np.ndarray, rate: float, times: np.ndarray) -> np.ndarray:
    """``values`` (S, ...) sampled at ``rate`` from time 0, linearly interpolated at
    ``times`` (T,) seconds (clamped to the samples).

    >>> at_times(np.array([0.0, 10.0, 20.0]), 1.0, np.array([0.5, 1.25, 5.0]))
    array([ 5. , 12.5, 20. ])
    """
    x = np.clip(np.asarray(times, float) * rate, 0, len(values) - 1)
    i = np.minimum(np.floor(x).astype(int), len(values) - 2) if len(values) > 1 else x.astype(int)
    if len(values) == 1:
        return np.repeat(values, len(x), axis=0)
    f = (x - i).reshape(-1, *([1] * (values.ndim - 1)))
    return ((1 - f) * values[i] + f * values[i + 1]).astype(values.dtype)
