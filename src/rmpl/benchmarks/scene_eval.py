"""Multi-person MHP scenes: per-person MPJPE and the share of people found, per view subset.

Usage: python -m rmpl.benchmarks.scene_eval DIR [--views 4] [--single DIR] [--methods NAME,...]
       [--model default] [--csv FILE]

DIR is a scene set of ``rmpl generate`` (``people = [2, 4]``, e.g. the held-out CMU subject
03 set of ``configs/mhp_scenes_heldout.toml``); ``--single`` a one-body set made by the same
rules (``configs/mhp_single_heldout.toml``), read as scenes of one body, whose figure the
ratios are taken against. For each scene and each subset of ``--views`` of its views, the
per-frame chain of ``rmpl run`` runs on the unassociated detections: keypoints far outside
their image dropped, the 2D people associated across views
(:func:`rmpl.pipeline.runner.associate_frames`, default thresholds), then every associated
person estimated by each method (``rmpl``: the shipped per-frame lifter; ``triangulate``,
``robust``: ``rmpl run``'s triangulations). ``rmpl:given`` lifts the detections the
generator matched to each body (``match``) instead: association known, to separate
association from occlusion.

Scoring (:func:`score_subset`):

- estimates are matched to the scene's bodies by the Hungarian method on the mean distance
  of the KP* joints (the 12 limb joints), and a pair further than :data:`MISS_GATE` (0.5 m,
  the gate of ``rmpl evaluate``'s multi-person protocol) is no match: the body is missed and
  the estimate spurious;
- MPJPE per person: mean over the KP* joints the method estimated of a matched body, mm;
  the tables average persons (body x subset);
- a view *sees* a body in two ways: ``det``, the detector has a slot the generator matched
  to the body (the set's ``match``: median keypoint distance within 0.2 of the body's
  projected size); ``proj``, at least :data:`MIN_VISIBLE` of the body's 12 KP* joints
  project inside the image and are not drawn over by another body (the set's ``hidden``).
  Found rates count the bodies at least two views of the subset see. The MPJPE is given
  over every found person, and over those every view of the subset detects (the figure
  that compares bodies seen alike, with and without other people around).

Joints beyond the first 17 (a 26-joint set or lifter) are ignored: COCO-17 is scored.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.benchmarks._common import run_main, set_rig
from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.io.keypoints import drop_far_keypoints
from rmpl.pipeline.association import Association, match_poses
from rmpl.pipeline.runner import RunConfig, _estimator, associate_frames
from rmpl.skeleton import KP_STAR

#: A body and an estimate further apart (mean KP* distance, metres) are no match.
MISS_GATE = 0.5
#: A view sees a body (``proj``) when this many of its 12 KP* joints are in the image, shown.
MIN_VISIBLE = 6
#: Arrays a scene set's shards must hold (``rmpl.synth.generate.SCENE_ARRAYS``).
SCENE_KEYS = ("joints3d", "present", "keypoints", "scores", "match", "projected", "hidden")
#: Arrays a one-body set's shards must hold (``rmpl.synth.generate.SHARD_ARRAYS``).
SINGLE_KEYS = ("joints3d", "keypoints", "scores", "projected")
CAMERA_KEYS = ("K", "R", "t", "size")

Method = Callable[[np.ndarray, np.ndarray, Rig], np.ndarray]


# ------------------------------------------------------------------------------- reading


def load_scenes(folder: str | Path) -> dict[str, np.ndarray]:
    """Every shard of a scene set or a one-body set, as scene arrays (first 17 joints).

    Returns:
        joints3d (M, P, 17, 3), present (M, P), keypoints (M, V, N, 17, 2), scores
        (M, V, N, 17), match (M, V, N), projected (M, V, P, 17, 2), hidden (M, V, P, 17),
        K (M, V, 3, 3), R (M, V, 3, 3), t (M, V, 3), size (M, V, 2). A one-body set has
        P = N = 1, ``hidden`` all False, and ``match`` computed as the generator does.
    """
    from rmpl.synth.generate import list_shards

    shards = list_shards(folder)
    if not shards:
        raise InputError(folder, None, "shard_*.npz files of rmpl generate", "none")
    parts: dict[str, list] = {}
    for path in shards:
        with np.load(path) as z:
            scene = "present" in z.files
            need = (SCENE_KEYS if scene else SINGLE_KEYS) + CAMERA_KEYS
            missing = [k for k in need if k not in z.files]
            if missing:
                raise InputError(path, missing[0], "an rmpl generate shard array", "absent")
            d = {k: z[k] for k in need}
        d = _clip_joints(d if scene else _as_scenes(d))
        for k, v in d.items():
            parts.setdefault(k, []).append(v)
    views = {v.shape[1] for v in parts["keypoints"]}
    if len(views) > 1:
        raise InputError(folder, "keypoints", "one view count in every shard", sorted(views))
    return {k: _concat(v) for k, v in parts.items()}


def _concat(arrays: list[np.ndarray]) -> np.ndarray:
    """Concatenate on the scene axis, padding the people axes (shards may differ in N)."""
    shape = np.max([a.shape for a in arrays], axis=0)
    out = []
    for a in arrays:
        pad = [(0, 0)] + [(0, int(s - n)) for s, n in zip(shape[1:], a.shape[1:], strict=True)]
        fill = {np.bool_: False, np.int8: -1}.get(
            a.dtype.type, np.nan if a.dtype.kind == "f" else 0
        )
        out.append(np.pad(a, pad, constant_values=fill))
    return np.concatenate(out)


def _clip_joints(d: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Keep COCO-17, the first 17 joints (a set extended to 26 joints keeps them first)."""
    d = dict(d)
    for k in ("joints3d", "keypoints", "projected"):
        d[k] = d[k][..., :17, :]
    for k in ("scores", "hidden"):
        d[k] = d[k][..., :17]
    return d


def _as_scenes(d: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A one-body shard (M, V, J, ...) as scenes of one body with one detector slot."""
    from rmpl.synth.generate import match_detections

    J = min(d["joints3d"].shape[-2], 17)
    kp = d["keypoints"][:, :, None, :J]  # (M, V, 1, J, 2)
    sc = d["scores"][:, :, None, :J]
    proj = d["projected"][:, :, None, :J]  # (M, V, 1, J, 2)
    present = np.ones((len(kp), 1), bool)
    match = np.array(
        [[match_detections(kp[m, v], sc[m, v], proj[m, v], present[m]) for v in range(kp.shape[1])]
         for m in range(len(kp))]
    ).reshape(kp.shape[:3])  # fmt: skip
    return {
        "joints3d": d["joints3d"][:, None, :J],
        "present": present,
        "keypoints": kp,
        "scores": sc,
        "match": match.astype(np.int8),
        "projected": proj,
        "hidden": np.zeros(proj.shape[:-1], bool),
        **{k: d[k] for k in CAMERA_KEYS},
    }


def scene_rig(d: dict[str, np.ndarray], m: int, views: tuple[int, ...]) -> Rig:
    """The cameras ``views`` of scene ``m``."""
    return set_rig(d, m, views, prefix="cam")


# ------------------------------------------------------------------------------- scoring


def seen_by_detector(match: np.ndarray, num_bodies: int) -> np.ndarray:
    """Which views' detector found each body: match (V, N) -> (V, P) bool."""
    return (match[:, :, None] == np.arange(num_bodies)).any(1)


def seen_by_projection(
    projected: np.ndarray, hidden: np.ndarray, size: np.ndarray, least: int = MIN_VISIBLE
) -> np.ndarray:
    """Which views show each body: at least ``least`` KP* joints inside the image and not
    hidden. projected (V, P, J, 2) px, hidden (V, P, J) (or False), size (V, 2) -> (V, P)."""
    wh = size[:, None, None].astype(float)  # (V, 1, 1, 2)
    with np.errstate(invalid="ignore"):
        inside = ((projected >= 0) & (projected < wh)).all(-1)  # NaN (no body) is outside
    shown = inside & ~hidden
    return shown[..., list(KP_STAR)].sum(-1) >= least


def person_errors(pred: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Match estimates to bodies and score them.

    Args:
        pred: (N, 17, 3) estimates, metres (NaN = not estimated); gt: (P, 17, 3) bodies.

    Returns:
        index (P,) of each body's estimate (-1 = missed, gate :data:`MISS_GATE`) and its
        KP* MPJPE (P,) mm (NaN when missed).
    """
    idx = match_poses(pred, gt, MISS_GATE, KP_STAR)
    err = np.full(len(gt), np.nan)
    for p in np.flatnonzero(idx >= 0):
        d = np.linalg.norm(pred[idx[p]][list(KP_STAR)] - gt[p][list(KP_STAR)], axis=-1)
        err[p] = 1000 * np.nanmean(d)
    return idx, err


def given_people(kp: np.ndarray, sc: np.ndarray, match: np.ndarray, num_bodies: int):
    """Per body, the detections matched to it: (P, V, J, 2), (P, V, J) and the bodies with
    at least two views (P,) bool (the association's ``min_views``)."""
    V, _, J = sc.shape
    out_kp = np.full((num_bodies, V, J, 2), np.nan)
    out_sc = np.zeros((num_bodies, V, J))
    for v, n in zip(*np.nonzero(match >= 0), strict=True):
        out_kp[match[v, n], v], out_sc[match[v, n], v] = kp[v, n], sc[v, n]
    return out_kp, out_sc, (out_sc > 0).any(-1).sum(-1) >= 2


@dataclass
class Person:
    """One body seen by one view subset, for one method."""

    scene: int
    subset: tuple[int, ...]
    body: int
    method: str
    seen_det: int
    seen_proj: int
    hidden: int
    outside: int
    found: bool
    mpjpe: float


def score_subset(
    d: dict[str, np.ndarray], m: int, views: tuple[int, ...], methods: dict[str, Method]
) -> tuple[list[Person], dict[str, int]]:
    """Every method on scene ``m`` seen by ``views``: one :class:`Person` per (body,
    method), and per method the count of spurious estimates (matched to no body)."""
    v = list(views)
    rig = scene_rig(d, m, views)
    bodies = np.flatnonzero(d["present"][m])
    gt = d["joints3d"][m, bodies].astype(float)  # (P, 17, 3)
    kp, sc, _ = drop_far_keypoints(
        d["keypoints"][m, v].astype(float), d["scores"][m, v].astype(float), rig.sizes, -4
    )  # (V, N, J, 2), (V, N, J)
    match = d["match"][m, v]
    det = seen_by_detector(match, d["present"].shape[1])[:, bodies].sum(0)
    proj = seen_by_projection(
        d["projected"][m, v], d["hidden"][m, v], d["size"][m, v]
    )[:, bodies].sum(0)  # fmt: skip
    star = list(KP_STAR)
    hidden = d["hidden"][m, v][:, bodies][..., star].sum((0, 2))  # (P,) over the views
    outside = (~seen_by_projection(d["projected"][m, v], False, d["size"][m, v], 12))[:, bodies]
    outside = outside.sum(0)  # views where some KP* joint projects outside the image
    assoc = associate_frames(kp[None], sc[None], rig)[0]
    given_kp, given_sc, given_ok = given_people(kp, sc, match, d["present"].shape[1])
    people, spurious = [], {}
    for name, fn in methods.items():
        if name.endswith(":given"):
            keep = given_ok[bodies]
            pred = np.full((len(bodies), 17, 3), np.nan)
            if keep.any():
                pred[keep] = fn(given_kp[bodies][keep], given_sc[bodies][keep], rig)[..., :17, :]
            idx, err = _identity(pred, gt)
        else:
            pred = _estimate(fn, assoc, rig)
            idx, err = person_errors(pred, gt)
            spurious[name] = len(pred) - int((idx >= 0).sum())
        for i, b in enumerate(bodies):
            people.append(
                Person(m, views, int(b), name, int(det[i]), int(proj[i]), int(hidden[i]),
                       int(outside[i]), bool(idx[i] >= 0), float(err[i]))
            )  # fmt: skip
    return people, spurious


def _estimate(fn: Method, assoc: Association, rig: Rig) -> np.ndarray:
    if len(assoc) == 0:
        return np.zeros((0, 17, 3))
    return np.asarray(fn(assoc.keypoints, assoc.scores, rig))[..., :17, :]


def _identity(pred: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Known identity: body p's estimate is row p, kept when within the gate."""
    idx, err = np.full(len(gt), -1), np.full(len(gt), np.nan)
    for p in range(len(gt)):
        d = np.linalg.norm(pred[p][list(KP_STAR)] - gt[p][list(KP_STAR)], axis=-1)
        if np.isfinite(d).any() and np.nanmean(d) <= MISS_GATE:
            idx[p], err[p] = p, 1000 * np.nanmean(d)
    return idx, err


def make_methods(names: list[str], model: str) -> dict[str, Method]:
    """name -> ``fn(kp (N, V, J, 2), sc (N, V, J), rig) -> (N, J, 3)`` as ``rmpl run``'s
    per-frame estimators; ``NAME:given`` is NAME on the generator's association."""
    out = {}
    for name in names:
        base = name.removesuffix(":given")
        if base not in ("rmpl", "triangulate", "robust"):
            raise InputError(None, "--methods", "rmpl, triangulate, robust (:given)", name)
        est = _estimator(RunConfig(method=base, model=model))
        out[name] = lambda kp, sc, rig, est=est: est(kp, sc, rig)[0]
    return out


def evaluate_set(d: dict[str, np.ndarray], k: int, methods: dict[str, Method]):
    """Every scene x every k-subset of its views. Returns the persons and the spurious
    counts per method (summed), and the number of (scene, subset) pairs."""
    V = d["keypoints"].shape[1]
    if not 1 <= k <= V:
        raise InputError(None, "--views", f"a view count in 1..{V}", k)
    people, pairs = [], 0
    spurious = {name: 0 for name in methods if not name.endswith(":given")}
    for m in range(len(d["joints3d"])):
        for views in itertools.combinations(range(V), k):
            p, s = score_subset(d, m, views, methods)
            people += p
            pairs += 1
            for name, n in s.items():
                spurious[name] += n
    return people, spurious, pairs


def summarize(people: list[Person], method: str) -> dict[str, float]:
    """found rates (%) among bodies 2+ views see (det, proj), and MPJPE (mm) of found."""
    rows = [p for p in people if p.method == method]
    out = {"persons": len(rows)}
    for key in ("seen_det", "seen_proj"):
        seen = [p for p in rows if getattr(p, key) >= 2]
        out[f"n_{key}"] = len(seen)
        out[f"found_{key}"] = 100 * np.mean([p.found for p in seen]) if seen else np.nan
    err = np.array([p.mpjpe for p in rows if p.found])
    out["found"] = len(err)
    out["mpjpe"] = float(err.mean()) if len(err) else np.nan
    out["median"] = float(np.median(err)) if len(err) else np.nan
    every = np.array([p.mpjpe for p in rows if p.found and p.seen_det == len(p.subset)])
    out["n_every"] = len(every)
    out["mpjpe_every"] = float(every.mean()) if len(every) else np.nan
    return out


# ------------------------------------------------------------------------------ the table


def table(results: dict[str, tuple], methods: list[str], k: int) -> str:
    """Markdown: one row per (set, method); the MPJPE ratio to the one-body set's."""
    single = results.get("one body")
    lines = [
        f"| set | method | {k}-view subsets | persons | found, 2+ views detect (det) | "
        "found, 2+ views show (proj) | spurious per subset | KP* MPJPE mean / median (mm) "
        "| mean / one body | every view detects: persons, MPJPE (mm) | ... / one body |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for label, (people, spurious, pairs) in results.items():
        for name in methods:
            s = summarize(people, name)
            ref = summarize(single[0], name) if single else {"mpjpe": np.nan, "mpjpe_every": np.nan}
            spur = f"{spurious[name] / pairs:.3f}" if name in spurious else "-"
            lines.append(
                f"| {label} | {name} | {pairs} | {s['persons']} "
                f"| {s['found_seen_det']:.1f}% of {s['n_seen_det']} "
                f"| {s['found_seen_proj']:.1f}% of {s['n_seen_proj']} | {spur} "
                f"| {s['mpjpe']:.1f} / {s['median']:.1f} | {s['mpjpe'] / ref['mpjpe']:.3f} "
                f"| {s['n_every']}, {s['mpjpe_every']:.1f} "
                f"| {s['mpjpe_every'] / ref['mpjpe_every']:.3f} |"
            )
    return "\n".join(lines)


def breakdown(results: dict[str, tuple], method: str, k: int) -> str:
    """Markdown: ``method``'s MPJPE of found persons by how many views detect them, and of
    those every view detects, by mutual occlusion and by the image border."""
    groups: dict[str, Callable[[Person], bool]] = {
        f"{n} of {k} views detect": (lambda p, n=n: p.seen_det == n) for n in range(2, k + 1)
    }
    groups |= {
        "all detect, whole body in every image, no KP* joint hidden": lambda p: (
            p.seen_det == k and p.outside == 0 and p.hidden == 0
        ),
        "all detect, whole body in every image, some KP* joint hidden": lambda p: (
            p.seen_det == k and p.outside == 0 and p.hidden > 0
        ),
        "all detect, some KP* joint outside an image": lambda p: p.seen_det == k and p.outside > 0,
    }
    lines = [
        f"| {method}: persons found | " + " | ".join(results) + " |",
        "|---|" + "---:|" * len(results),
    ]
    for label, rule in groups.items():
        cells = []
        for people, _, _ in results.values():
            err = np.array([p.mpjpe for p in people if p.method == method and p.found and rule(p)])
            cells.append(f"{len(err)}: {err.mean():.1f} mm" if len(err) else "0")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_csv(path: str | Path, results: dict[str, tuple]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["set", "scene", "views", "body", "method", "seen_det", "seen_proj",
                    "hidden_kpstar", "views_cut", "found", "mpjpe_mm"])  # fmt: skip
        for label, (people, _, _) in results.items():
            for p in people:
                w.writerow([label, p.scene, " ".join(map(str, p.subset)), p.body, p.method,
                            p.seen_det, p.seen_proj, p.hidden, p.outside, int(p.found),
                            f"{p.mpjpe:.2f}"])  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", help="a scene set (rmpl generate, people = [2, 4])")
    ap.add_argument("--views", type=int, default=4, help="views per subset (every subset)")
    ap.add_argument("--single", help="a one-body set made by the same rules, for the ratio")
    ap.add_argument("--methods", default="rmpl,triangulate,robust,rmpl:given")
    ap.add_argument("--model", default="default", help="the per-frame lifter")
    ap.add_argument("--csv", help="write one row per person, subset and method")
    args = ap.parse_args(argv)
    names = [n.strip() for n in args.methods.split(",") if n.strip()]
    methods = make_methods(names, args.model)
    results = {}
    t0 = time.perf_counter()
    for label, folder in (("scenes", args.dir), ("one body", args.single)):
        if folder:
            results[label] = evaluate_set(load_scenes(folder), args.views, methods)
    print(table(results, names, args.views))
    print()
    print(breakdown(results, names[0], args.views))
    print(f"({time.perf_counter() - t0:.0f} s; miss gate {MISS_GATE} m mean KP* distance; "
          f"proj = {MIN_VISIBLE}+ of 12 KP* joints in the image and not hidden)")  # fmt: skip
    if args.csv:
        write_csv(args.csv, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
