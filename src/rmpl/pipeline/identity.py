"""Identities that hold: the tracker's fragments joined into one track per person.

The tracker (:mod:`rmpl.pipeline.tracking`) links a person from frame to frame; a person it
loses for longer than its ``max_missed`` frames (out of the views, occluded) comes back as
a new track, and one person split by the association into two 3D people gives two tracks
side by side. :func:`resolve` takes its fragments and applies, in order, these rules
(written down before any recording was run; distances are relative to the person's size,
speeds are physical limits):

1. **Duplicates.** Two fragments present in the same frames whose torso centres (the mean
   of shoulders and hips) stay closer than ``duplicate_distance`` x the body height (median
   over the shared frames) are one person seen twice: two people's torsos cannot come that
   close (an adult's chest depth is roughly 0.13-0.15 of the stature in anthropometric
   surveys, e.g. ANSUR II). The shorter fragment is merged into the longer: its frames
   where the longer one is absent join it, the shared ones are dropped.
2. **Re-linking across gaps.** A fragment that ends and one that starts later are the same
   person when (a) the distance between where the first was last seen and where the second
   appears is reachable: at most ``position_slack`` x the height plus ``max_speed`` (m/s)
   times the gap, and (b) their bodies match: the median relative difference of their
   segment lengths (:func:`rmpl.anthropometry.body_segments`: upper arms, forearms, thighs,
   shanks, shoulder and hip width, trunk) is at most ``body_tolerance`` (a body measured on
   too few frames is not compared). Among the candidates the assignment (Hungarian) takes
   the least total cost: the distance from the first fragment's constant-velocity
   prediction (at most one second ahead) over the reachable radius, plus the body
   difference over its tolerance. After a long absence position says little and the body
   decides: a person who leaves and returns keeps their identity when the body matches.
3. **Known number of people** (``people``): when there are more identities than that, the
   longest becomes the first person, then each next longest one present together with all
   the people chosen so far (surely someone else), until there are ``people``; every other
   identity, longest first, joins the person, of those it never coexists with, whose body
   and motion fit best (no gate: the user says who can be there), and is dropped when it
   coexists with all of them.
4. **Too short.** An identity seen in fewer than ``min_frames`` frames is dropped.
5. **Ghosts.** An identity shorter than ``ghost_seconds`` that is never seen by more than
   ``ghost_max_views`` views, while in most of its frames at least ``ghost_min_cameras``
   cameras have it inside their image, is a detector's or the association's ghost: a real
   person standing where three cameras look is detected by more than two of them. With
   fewer cameras the rule cannot tell and does nothing.

Every merge and drop is recorded (:class:`Identities`), and the run report lists them
(:mod:`rmpl.pipeline.report`).

Shape glossary: ``T`` frames, ``N`` people of one frame, ``F`` tracker fragments, ``P``
identities, ``J`` joints. Metres, seconds.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from dataclasses import dataclass, field

import numpy as np

from rmpl.errors import InputError

__all__ = ["IdentityConfig", "Identities", "resolve", "view_counts"]

#: Body height assumed for a fragment whose height cannot be measured, metres.
DEFAULT_HEIGHT = 1.70
#: Frame rate assumed for speeds when the run has none (frames/s): a low common video rate,
#: so that the reachable distance per frame errs on the generous side.
ASSUMED_FPS = 25.0
_TORSO = [5, 6, 11, 12]  # COCO-17 shoulders and hips
_REFUSED = 1e9
_PREDICT_SECONDS = 1.0  # a constant-velocity prediction reaches at most this far ahead
_VELOCITY_SECONDS = 0.5  # the velocity at a fragment's end: over its last half second


@dataclass(frozen=True)
class IdentityConfig:
    """The rules of :func:`resolve` (see the module docstring for why each value).

    Attributes:
        duplicate_distance: two coexisting fragments whose torso centres are closer than
            this fraction of the height (median over shared frames) are one person.
        max_speed: the fastest a person is followed across a gap, m/s (a run).
        position_slack: the reachable radius at no gap, as a fraction of the height.
        body_tolerance: largest median relative segment-length difference of one body.
        min_body_frames: a segment counts in a body when seen in this many frames.
        people: the number of people, when known; None: not known.
        min_frames: identities seen in fewer frames are dropped (1 keeps all).
        ghost_seconds, ghost_max_views, ghost_min_cameras: the ghost rule (rule 5).
    """

    duplicate_distance: float = 0.10
    max_speed: float = 4.0
    position_slack: float = 0.20
    body_tolerance: float = 0.15
    min_body_frames: int = 3
    people: int | None = None
    min_frames: int = 1
    ghost_seconds: float = 1.0
    ghost_max_views: int = 2
    ghost_min_cameras: int = 3

    def __post_init__(self) -> None:
        for name in ("duplicate_distance", "max_speed", "position_slack", "body_tolerance",
                     "ghost_seconds"):  # fmt: skip
            value = getattr(self, name)
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
                raise InputError(None, name, "a number > 0", value)
        for name in ("min_body_frames", "min_frames", "ghost_max_views", "ghost_min_cameras"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise InputError(None, name, "an integer >= 1", value)
        p = self.people
        if p is not None and (isinstance(p, bool) or not isinstance(p, int | np.integer) or p < 1):
            raise InputError(None, "--people", "a number of people >= 1", p)


@dataclass
class Identities:
    """The identities :func:`resolve` found and how.

    Attributes:
        index: (T, P) the person of each identity in each frame's array, -1 where absent;
            identities ordered by first frame.
        fragments: per identity, the tracker's fragments it is made of (numbers of the
            input index's columns).
        merges: one dict per merge: ``kind`` ("duplicate", "relinked", "people"),
            ``fragment`` and ``into`` (fragment numbers), and the evidence (``gap_frames``,
            ``distance_m``, ``body_difference``, ``frames_added``, ``frames_dropped``).
        drops: one dict per dropped fragment: ``kind`` ("short", "ghost", "people"),
            ``fragment``, ``frames`` and ``reason``.
        num_fragments: the tracker's fragments.
    """

    index: np.ndarray
    fragments: list[list[int]]
    merges: list[dict] = field(default_factory=list)
    drops: list[dict] = field(default_factory=list)
    num_fragments: int = 0
    config: IdentityConfig = field(default_factory=IdentityConfig)

    def to_json(self) -> dict:
        """The record as plain JSON types (``report.json`` ``identity``)."""
        return {
            "fragments": self.num_fragments,
            "tracks": len(self.fragments),
            "track_fragments": [list(f) for f in self.fragments],
            "frames": [int(n) for n in (self.index >= 0).sum(0).tolist()],
            "merges": [dict(m) for m in self.merges],
            "drops": [dict(d) for d in self.drops],
            "settings": dataclasses.asdict(self.config),
        }


@dataclass
class _Fragment:
    """One identity while it is built: its frames and what is known of its body."""

    number: int  # the first fragment's column in the input index
    rows: dict[int, int]  # frame -> person index in that frame
    parts: list[int]
    centre: dict[int, np.ndarray] = field(default_factory=dict)  # frame -> (3,)
    body: dict[str, float] = field(default_factory=dict)
    height: float = DEFAULT_HEIGHT
    first: int = 0  # the first and last frames, kept up to date by _absorb
    last: int = 0

    def __post_init__(self) -> None:
        self.first, self.last = min(self.rows), max(self.rows)


def _centre(pose: np.ndarray) -> np.ndarray:
    """The torso centre (3,) of a pose (J, 3): mean of the shoulders and hips present, else
    of every joint present; NaN when none."""
    torso = pose[_TORSO]
    torso = torso[np.isfinite(torso).all(-1)]
    if len(torso):
        return torso.mean(0)
    seen = pose[np.isfinite(pose).all(-1)]
    return seen.mean(0) if len(seen) else np.full(3, np.nan)


def _describe(frag: _Fragment, frames: list[np.ndarray], cfg: IdentityConfig) -> None:
    """Fill a fragment's centres, body segments and height from the per-frame poses."""
    from rmpl.anthropometry import body_segments, estimate_height

    ts = sorted(frag.rows)
    pts = np.stack([frames[t][frag.rows[t]][:17] for t in ts])  # (n, 17, 3)
    frag.centre = {t: c for t, c in zip(ts, map(_centre, pts), strict=True) if np.isfinite(c).all()}
    frag.body = body_segments(pts, "coco17", cfg.min_body_frames)
    try:
        frag.height = float(np.clip(estimate_height(pts, "coco17", cfg.min_body_frames), 1.0, 2.3))
    except InputError:
        frag.height = DEFAULT_HEIGHT


def body_difference(a: dict[str, float], b: dict[str, float]) -> float:
    """Median over the segments both bodies have of ``|a - b| / mean(a, b)``; NaN when they
    share none.

    >>> round(body_difference({"thigh": 0.4, "shank": 0.4}, {"thigh": 0.44, "shank": 0.4}), 4)
    0.0476
    """
    common = [k for k in a if k in b and a[k] + b[k] > 0]
    if not common:
        return float("nan")
    return float(statistics.median(abs(a[k] - b[k]) / (0.5 * (a[k] + b[k])) for k in common))


def _edge(frag: _Fragment, end: bool, fps: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(position, velocity m/s, frame) at a fragment's end (or start)."""
    ts = sorted(frag.centre)
    if not ts:
        return np.full(3, np.nan), np.zeros(3), frag.last if end else frag.first
    t = ts[-1] if end else ts[0]
    span = max(1, int(round(_VELOCITY_SECONDS * fps)))
    near = [s for s in ts if abs(s - t) <= span and s != t]
    velocity = np.zeros(3)
    if near:
        s = min(near) if end else max(near)
        velocity = (frag.centre[t] - frag.centre[s]) / ((t - s) / fps)
    return frag.centre[t], velocity, t


def _link_cost(a: _Fragment, b: _Fragment, fps: float, cfg: IdentityConfig, gate: bool,
               edges=None):  # fmt: skip
    """(cost, evidence) of ``b`` continuing ``a`` (``b`` starts after ``a`` ends); cost
    None when refused. ``edges``: ``a``'s end and ``b``'s start when already known."""
    (pa, va, ta), (pb, _, tb) = edges or (_edge(a, True, fps), _edge(b, False, fps))
    if tb <= ta:
        return None, {}
    dt = (tb - ta) / fps
    reach = cfg.position_slack * 0.5 * (a.height + b.height) + cfg.max_speed * dt
    distance = math.dist(pa, pb)  # NaN when a fragment has no centre
    if not np.isfinite(distance) or (gate and distance > reach):
        return None, {}
    body = body_difference(a.body, b.body)
    evidence = {"gap_frames": int(tb - ta), "distance_m": round(distance, 3),
                "body_difference": None if np.isnan(body) else round(body, 3)}  # fmt: skip
    if gate and np.isfinite(body) and body > cfg.body_tolerance:
        return None, evidence
    speed = math.hypot(*va)
    ahead = min(dt, _PREDICT_SECONDS) * (min(1.0, cfg.max_speed / speed) if speed > 0 else 0.0)
    predicted = [p + v * ahead for p, v in zip(pa, va, strict=True)]
    body_cost = 0.5 if np.isnan(body) else body / cfg.body_tolerance
    return math.dist(pb, predicted) / reach + body_cost, evidence


def _absorb(into: _Fragment, other: _Fragment) -> tuple[int, int]:
    """Move ``other``'s frames where ``into`` is absent into it; (added, dropped)."""
    added = [t for t in other.rows if t not in into.rows]
    for t in added:
        into.rows[t] = other.rows[t]
        if t in other.centre:
            into.centre[t] = other.centre[t]
    into.parts += other.parts
    into.first, into.last = min(into.first, other.first), max(into.last, other.last)
    return len(added), len(other.rows) - len(added)


def _duplicates(frags: list[_Fragment], cfg: IdentityConfig, merges: list[dict]) -> None:
    """Rule 1, shortest fragments first; merged fragments leave ``frags``."""
    for short in sorted(frags, key=lambda f: (len(f.rows), -f.number)):
        best, best_d = None, np.inf
        for long in frags:
            if long is short or len(long.rows) < len(short.rows):
                continue
            if long.first > short.last or long.last < short.first:
                continue
            shared = [t for t in short.centre if t in long.centre]
            if not shared:
                continue
            d = np.median([np.linalg.norm(short.centre[t] - long.centre[t]) for t in shared])
            limit = cfg.duplicate_distance * 0.5 * (short.height + long.height)
            if d < limit and d < best_d:
                best, best_d = long, d
        if best is not None:
            added, dropped = _absorb(best, short)
            frags.remove(short)
            merges.append({"kind": "duplicate", "fragment": short.number, "into": best.number,
                           "distance_m": round(float(best_d), 3), "frames_added": added,
                           "frames_dropped": dropped})  # fmt: skip


def _relink(frags: list[_Fragment], fps: float, cfg: IdentityConfig, merges: list[dict]):
    """Rule 2: one assignment of fragment ends to later fragment starts; chains join."""
    from scipy.optimize import linear_sum_assignment

    n = len(frags)
    if n < 2:
        return frags
    cost = np.full((n, n), _REFUSED)
    evidence = {}
    ends = [_edge(f, True, fps) for f in frags]
    starts = [_edge(f, False, fps) for f in frags]
    for i, a in enumerate(frags):
        for j, b in enumerate(frags):
            if i != j and b.first > a.last:
                c, ev = _link_cost(a, b, fps, cfg, gate=True, edges=(ends[i], starts[j]))
                if c is not None:
                    cost[i, j], evidence[i, j] = c, ev
    rows, cols = linear_sum_assignment(cost)
    successor = {int(r): int(c) for r, c in zip(rows, cols, strict=True) if cost[r, c] < _REFUSED}
    heads = set(range(n)) - set(successor.values())
    out = []
    for h in sorted(heads, key=lambda k: frags[k].first):
        chain, k = frags[h], h
        while k in successor:
            nxt = successor[k]
            merges.append({"kind": "relinked", "fragment": frags[nxt].number,
                           "into": chain.number, **evidence[k, nxt]})  # fmt: skip
            _absorb(chain, frags[nxt])
            chain.body = _merged_body(chain.body, frags[nxt].body)
            k = nxt
        out.append(chain)
    return out


def _merged_body(a: dict[str, float], b: dict[str, float]) -> dict[str, float]:
    return {k: float(np.mean([d[k] for d in (a, b) if k in d])) for k in {*a, *b}}


def _coexist(a: _Fragment, b: _Fragment) -> bool:
    return not a.rows.keys().isdisjoint(b.rows.keys())


def _to_people(frags, fps: float, cfg: IdentityConfig, merges: list[dict], drops: list[dict]):
    """Rule 3: ``cfg.people`` seeds (the longest identity, then each next longest present
    together with every seed so far: surely another person), then every other identity,
    longest first, joins the seed it never coexists with that fits best, or is dropped."""
    if len(frags) <= cfg.people:
        return frags
    order = sorted(frags, key=lambda f: (-len(f.rows), f.number))
    seeds = [order[0]]
    for f in order[1:]:
        if len(seeds) < cfg.people and all(_coexist(f, s) for s in seeds):
            seeds.append(f)
    seeds += [f for f in order if f not in seeds][: cfg.people - len(seeds)]
    for f in [f for f in order if f not in seeds]:
        best, best_cost, best_ev = None, np.inf, {}
        for seed in seeds:
            if _coexist(f, seed):
                continue
            first, second = (seed, f) if seed.first < f.first else (f, seed)
            c, ev = _link_cost(first, second, fps, cfg, gate=False)
            if c is None:  # interleaved in time: judge by the body alone
                body = body_difference(f.body, seed.body)
                c, ev = (0.5 if np.isnan(body) else body / cfg.body_tolerance), {}
            if c < best_cost:
                best, best_cost, best_ev = seed, c, ev
        if best is None:
            reason = f"present together with each of the {cfg.people} people"
            drops.append({"kind": "people", "fragment": f.number, "frames": len(f.rows),
                          "reason": reason})  # fmt: skip
            continue
        _absorb(best, f)
        best.body = _merged_body(best.body, f.body)
        merges.append({"kind": "people", "fragment": f.number, "into": best.number,
                       **best_ev})  # fmt: skip
    return seeds


def _ghosts(frags, fps: float, cfg: IdentityConfig, views, cameras, drops: list[dict]):
    """Rules 4 and 5."""
    keep = []
    longest = max(1, int(np.ceil(cfg.ghost_seconds * fps)))
    for f in frags:
        if len(f.rows) < cfg.min_frames:
            drops.append({"kind": "short", "fragment": f.number, "frames": len(f.rows),
                          "reason": f"seen in fewer than {cfg.min_frames} frames"})  # fmt: skip
            continue
        if views is not None and cameras is not None and len(f.rows) < longest:
            seen = max(int(views[t][i]) for t, i in f.rows.items())
            inside = np.mean([cameras[t][i] >= cfg.ghost_min_cameras for t, i in f.rows.items()])
            if seen <= cfg.ghost_max_views and inside > 0.5:
                drops.append({"kind": "ghost", "fragment": f.number, "frames": len(f.rows),
                              "reason": f"at most {seen} views detect it while "
                              f"{cfg.ghost_min_cameras} or more cameras have it in their "
                              "image"})  # fmt: skip
                continue
        keep.append(f)
    return keep


def resolve(
    poses_per_frame: list[np.ndarray],
    index: np.ndarray,
    config: IdentityConfig | None = None,
    fps: float | None = None,
    views: list[np.ndarray] | None = None,
    cameras: list[np.ndarray] | None = None,
) -> Identities:
    """Join the tracker's fragments into identities (rules 1-5 of the module docstring).

    Args:
        poses_per_frame: per frame the people's 3D joints (N_t, J, 3), metres, NaN = missing;
            their first 17 joints are COCO-17's.
        index: (T, F) each fragment's person per frame, -1 where absent
            (:func:`rmpl.pipeline.tracking.track_indices`).
        config: the rules' settings.
        fps: frames per second; None: :data:`ASSUMED_FPS` for the speeds.
        views: per frame, how many views detect each person (N_t,); with ``cameras`` (per
            frame, how many cameras have the person inside their image, (N_t,)) the ghost
            rule applies (:func:`view_counts` gives both); None: it does not.

    Returns:
        :class:`Identities`.
    """
    cfg = config or IdentityConfig()
    index = np.asarray(index)
    if index.ndim != 2 or index.shape[0] != len(poses_per_frame):
        raise InputError(None, "index", f"shape ({len(poses_per_frame)}, F)", index.shape)
    fps = float(fps) if fps else ASSUMED_FPS
    frags = []
    for k in range(index.shape[1]):
        rows = {int(t): int(index[t, k]) for t in np.flatnonzero(index[:, k] >= 0)}
        if rows:
            frag = _Fragment(k, rows, [k])
            _describe(frag, poses_per_frame, cfg)
            frags.append(frag)
    merges, drops = [], []
    _duplicates(frags, cfg, merges)
    frags = _relink(frags, fps, cfg, merges)
    if cfg.people is not None:
        frags = _to_people(frags, fps, cfg, merges, drops)
    frags = _ghosts(frags, fps, cfg, views, cameras, drops)
    frags.sort(key=lambda f: (f.first, f.rows[f.first]))
    out = np.full((index.shape[0], len(frags)), -1, np.int64)
    for p, f in enumerate(frags):
        for t, i in f.rows.items():
            out[t, p] = i
    return Identities(out, [sorted(f.parts) for f in frags], merges, drops, index.shape[1], cfg)


def view_counts(people, poses_per_frame: list[np.ndarray], rig) -> tuple[list, list]:
    """For :func:`resolve`'s ghost rule: per frame and person, the views that detect it
    (views with a keypoint of score > 0) and the cameras whose image holds its torso centre
    (in front of the camera, inside the image; cameras of unknown size never count).

    Args:
        people: per frame an object with ``scores`` (N, V, J) (an
            :class:`rmpl.pipeline.association.Association`).
        poses_per_frame: per frame the people's 3D joints (N, J, 3).
        rig: the :class:`rmpl.geometry.camera.Rig`.
    """
    sizes = rig.sizes  # (V, 2)
    views, cameras = [], []
    for a, pts in zip(people, poses_per_frame, strict=True):
        views.append((np.asarray(a.scores) > 0).any(-1).sum(-1) if len(pts) else np.zeros(0))
        if not len(pts):
            cameras.append(np.zeros(0, int))
            continue
        c = np.stack([_centre(p[:17]) for p in pts])  # (N, 3)
        ok = np.isfinite(c).all(-1)
        c = np.where(ok[:, None], c, 0.0)
        uv = rig.project(c)  # (V, N, 2)
        depth = np.einsum("vij,nj->vni", rig.R, c)[..., 2] + rig.t[:, None, 2]
        with np.errstate(invalid="ignore"):
            inside = ((uv >= 0) & (uv < sizes[:, None])).all(-1) & (depth > 0)
        cameras.append(np.where(ok, inside.sum(0), 0))
    return views, cameras
