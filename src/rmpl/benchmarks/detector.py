"""Multi-person 2D detectors on rendered scenes (recall, precision, 2D error) and their speed.

Usage::

    python -m rmpl.benchmarks.detector render CONFIG --out DIR [--scenes N] [--set K=V ...]
    python -m rmpl.benchmarks.detector score DIR --detectors NAME,... [--sets OUT]
    python -m rmpl.benchmarks.detector speed (--video FILE | --scenes-dir DIR)
        --detectors NAME,... [--frames N]

``render`` draws the first N scenes of an ``rmpl generate`` scene config (e.g.
``configs/mhp_scenes_heldout.toml``; with ``--set 'people=[1, 1]'`` one body per scene, the
single-body twin) exactly as the generator draws them (same seed, bodies, cameras, renders),
and keeps each scene's images (PNG) and truth in ``DIR/scene_<i>.npz``; it is resumable.
``score`` runs each detector (a name of :data:`rmpl.pipeline.detect2d.DETECTORS`, optionally
``name@key=value@...`` for constructor options, e.g. ``movenet-blazepose@input_size=384``)
on every image afresh and prints, per detector:

- recall: the share of shown (body, view) pairs (at least 6 of the body's 12 limb joints
  inside the image and not drawn over by another body) for which the detector has a person
  the generator's rule matches to the body (:func:`rmpl.synth.generate.match_detections`:
  median keypoint distance within 0.2 of the body's projected size);
- precision: the share of the detector's people (slots with any joint) matched to a body;
  a second detection of one body counts as a false one;
- the median 2D error of matched people (COCO-17 joints, % of the body's size) and the share
  of matched people with both heels;
- seconds per image.

With ``--sets OUT`` each detector's detections are written as a scene set
(``OUT/<detector>/shard_00000.npz``) that ``scripts/scene_eval.py`` scores (per-person MPJPE,
``--single`` for the ratio to single bodies).

The default detector of ``rmpl run --videos`` follows this rule, written before any
detector was run on these scenes or on the demos (:func:`choose_default`): eligible are the
detectors that give the feet (HALPE-26: heels and toes); among those whose precision is at
least 95%, the highest recall wins (if none reaches 95%, the most precise); two within one
percentage point of recall: the faster one. The MoveNet input size (256 or 384) is chosen by
the same rule.

``speed`` times detection in frames per second and view: ``--video`` a recording, frames
fed in order (people followed from frame to frame); ``--scenes-dir`` a rendered set (e.g.
``--set 'image_size=[1920, 1080]'``), every image afresh.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

__all__ = ["Recorder", "render", "score_detector", "choose_default", "main"]

#: A view shows a body when this many of its 12 limb joints are inside and not hidden.
MIN_VISIBLE = 6
#: Least precision of an eligible default.
MIN_PRECISION = 0.95
#: Recall within this of the best: the faster detector wins.
RECALL_TIE = 0.01
_TRUTH = ("joints3d", "present", "projected", "hidden", "K", "R", "t", "size")


class Recorder:
    """A stand-in detector that keeps the images it is given and finds nobody."""

    name = "recorder"

    def __init__(self) -> None:
        from rmpl.skeleton import COCO17

        self.skeleton = COCO17
        self.images: list[np.ndarray] = []

    def __call__(self, images):
        self.images.extend(np.asarray(im) for im in images)
        B = len(images)
        return np.full((B, 17, 2), np.nan), np.zeros((B, 17))

    def take(self) -> list[np.ndarray]:
        out, self.images = self.images, []
        return out


def render(config: str, out: Path, scenes: int, overrides: list[str]) -> int:
    """Render the first ``scenes`` scenes of a scene config into ``out``; returns how many
    were rendered now (the others were there)."""
    from tqdm import tqdm

    from rmpl.io.atomic import atomic_path
    from rmpl.synth import generate as g

    cfg = g.GenerateConfig.from_toml(config, overrides)
    cfg = replace(cfg, detector=f"{__name__}:Recorder", detector_options={})
    out.mkdir(parents=True, exist_ok=True)
    todo = [i for i in range(scenes) if not (out / f"scene_{i:05d}.npz").is_file()]
    if not todo:
        return 0
    worker = g.Worker(cfg, g._prepare_bank(cfg, out))
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    try:
        for i in tqdm(todo, desc="render", unit="scene"):
            rng = np.random.default_rng([cfg.seed, i, 3])  # the generator's scene stream
            row, _ = g._scene(worker, i, rng, times)
            pngs = [_png(im) for im in worker.detector.take()]
            arrays = {k: row[k] for k in _TRUTH}
            with atomic_path(out / f"scene_{i:05d}.npz") as tmp, open(tmp, "wb") as f:
                np.savez(
                    f, **arrays, png=np.concatenate(pngs), png_ends=np.cumsum(list(map(len, pngs)))
                )
    finally:
        worker.close()
    (out / "render.json").write_text(json.dumps({"config": config, "overrides": overrides}))
    return len(todo)


def _png(image: np.ndarray) -> np.ndarray:
    import cv2

    ok, buf = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError("OpenCV could not encode a rendered image as PNG")
    return buf.ravel()


def _scenes(folder: Path):
    """(index, truth arrays, RGB images) of every rendered scene, in order."""
    import cv2

    for path in sorted(folder.glob("scene_*.npz")):
        with np.load(path) as z:
            truth = {k: z[k] for k in _TRUTH}
            pngs = np.split(z["png"], z["png_ends"][:-1])
        images = [
            cv2.cvtColor(cv2.imdecode(b, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
            for b in pngs
        ]  # fmt: skip
        yield int(path.stem.split("_")[1]), truth, images


def _make(spec: str):
    """A detector from ``name`` or ``name@key=value@key=value...`` (JSON values)."""
    from rmpl.synth.generate import make_detector

    name, *options = spec.split("@")
    kwargs = {}
    for option in options:
        key, _, value = option.partition("=")
        kwargs[key] = json.loads(value)
    return make_detector(name, kwargs)


@dataclass
class Score:
    """One detector on one rendered set."""

    detector: str
    images: int
    shown: int
    recall: float
    precision: float
    error: float  # median 2D error of matched people, fraction of the body's size
    heels: float  # share of matched people with both heels
    seconds: float  # per image
    feet: bool  # the detector gives heels and toes


def _shown(truth: dict) -> np.ndarray:
    """(V, P) whether each view shows each body (see the module docstring)."""
    from rmpl.skeleton import KP_STAR

    proj = truth["projected"][..., :17, :]
    wh = truth["size"][:, None, None].astype(float)
    with np.errstate(invalid="ignore"):
        inside = ((proj >= 0) & (proj < wh)).all(-1)
    shown = inside & ~truth["hidden"][..., :17]
    return shown[..., list(KP_STAR)].sum(-1) >= MIN_VISIBLE


def score_detector(spec: str, folder: Path, sets: Path | None = None) -> Score:
    """Run one detector on every rendered image of ``folder`` and score it."""
    from tqdm import tqdm

    from rmpl.skeleton import skeleton_for
    from rmpl.synth import generate as g

    det = _make(spec)
    joints = "halpe26" if det.skeleton.name != "coco17" else "coco17"
    heel = [skeleton_for("halpe26").index(n) for n in ("left_heel", "right_heel")]
    shown = found = used = matched = images = 0
    errors, heels, seconds, rows = [], [], 0.0, []
    for _, truth, ims in tqdm(list(_scenes(folder)), desc=spec, unit="scene"):
        t0 = time.perf_counter()
        kp, sc = g._detect_people_apart(det, ims)  # (V, N, J, 2), (V, N, J)
        seconds += time.perf_counter() - t0
        kp, sc = g.in_joint_set(det, kp, sc, joints)
        proj, present = truth["projected"][..., :17, :], truth["present"]
        match = np.stack([
            g.match_detections(kp[v, :, :17], sc[v, :, :17], proj[v], present)
            for v in range(len(ims))
        ])  # fmt: skip
        seen = _shown(truth) & present[None]
        hit = (match[:, :, None] == np.arange(len(present))).any(1)  # (V, P)
        shown += int(seen.sum())
        found += int((seen & hit).sum())
        used += int((sc.max(-1) > 0).sum())
        matched += int((match >= 0).sum())
        images += len(ims)
        for v, n in zip(*np.nonzero(match >= 0), strict=True):
            p = match[v, n]
            size = max(np.ptp(proj[v, p], axis=0).max(), 1.0)
            ok = sc[v, n, :17] > 0
            errors.append(
                np.median(np.linalg.norm(kp[v, n, :17][ok] - proj[v, p][ok], axis=-1)) / size
            )
            heels.append(joints == "halpe26" and bool((sc[v, n, heel] > 0).all()))
        rows.append({**truth, "keypoints": kp.astype(np.float32), "scores": sc.astype(np.float32),
                     "match": match.astype(np.int8)})  # fmt: skip
    getattr(det, "close", lambda: None)()
    if sets is not None:
        _write_set(sets / spec.replace("@", "_").replace("=", ""), rows)
    return Score(
        spec, images, shown, found / max(shown, 1), matched / max(used, 1),
        float(np.median(errors)) if errors else float("nan"),
        float(np.mean(heels)) if heels else 0.0, seconds / max(images, 1), joints == "halpe26",
    )  # fmt: skip


def _write_set(out: Path, rows: list[dict]) -> None:
    """The detections as one shard of a scene set (``scripts/scene_eval.py`` reads it)."""
    from rmpl.io.atomic import atomic_path

    out.mkdir(parents=True, exist_ok=True)
    arrays = {}
    for k in rows[0]:
        parts = [r[k] for r in rows]
        if parts[0].ndim >= 2 and k in ("keypoints", "scores", "match"):  # pad the slots
            N = max(p.shape[1] for p in parts)
            fill = {"keypoints": np.nan, "scores": 0.0, "match": -1}[k]
            parts = [
                np.concatenate([p, np.full((p.shape[0], N - p.shape[1], *p.shape[2:]), fill,
                                           p.dtype)], axis=1)
                for p in parts
            ]  # fmt: skip
        arrays[k] = np.stack(parts)
    with atomic_path(out / "shard_00000.npz") as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)


def choose_default(scores: list[Score]) -> Score | None:
    """The rule of the module docstring: among detectors with feet, the highest recall of
    those at least :data:`MIN_PRECISION` precise (else the most precise); within
    :data:`RECALL_TIE` of that recall, the fastest."""
    eligible = [s for s in scores if s.feet]
    if not eligible:
        return None
    precise = [s for s in eligible if s.precision >= MIN_PRECISION]
    if not precise:
        return max(eligible, key=lambda s: s.precision)
    best = max(s.recall for s in precise)
    return min((s for s in precise if s.recall >= best - RECALL_TIE), key=lambda s: s.seconds)


def _table(scores: list[Score]) -> str:
    lines = [
        "| detector | images | shown pairs | recall | precision | 2D error (% size) "
        "| heels | s/image |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in scores:
        lines.append(
            f"| {s.detector} | {s.images} | {s.shown} | {100 * s.recall:.1f}% "
            f"| {100 * s.precision:.1f}% | {100 * s.error:.1f} | {100 * s.heels:.0f}% "
            f"| {s.seconds:.3f} |"
        )
    return "\n".join(lines)


def speed(spec: str, video: Path | None, scenes_dir: Path | None, frames: int) -> dict:
    """Frames per second and view of one detector (see the module docstring)."""
    from rmpl.synth.detect import with_people_axis

    det = _make(spec)
    if video is not None:
        from rmpl.pipeline.detect2d import probe_video, video_frames

        info = probe_video(video)
        ims = [im for _, im in zip(range(min(frames, info.num_frames)), video_frames(info),
                                   strict=False)]  # fmt: skip
        getattr(det, "reset", lambda: None)()
        t0 = time.perf_counter()
        people = []
        for k in range(0, len(ims), 8):
            kp, sc = with_people_axis(det, *det(ims[k : k + 8]), len(ims[k : k + 8]))
            people += list((sc.max(-1) > 0).sum(-1))
        dt = time.perf_counter() - t0
        size = info.size
    else:
        from rmpl.synth.generate import _detect_people_apart

        ims = [im for _, _, scene in _scenes(scenes_dir) for im in scene][:frames]
        t0 = time.perf_counter()
        _, sc = _detect_people_apart(det, ims)
        dt = time.perf_counter() - t0
        people = list((sc.max(-1) > 0).sum(-1))
        size = ims[0].shape[1::-1] if ims else (0, 0)
    getattr(det, "close", lambda: None)()
    return {"detector": spec, "frames": len(ims), "size": list(map(int, size)),
            "fps": len(ims) / dt, "people_per_frame": float(np.mean(people))}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rmpl.benchmarks.detector", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render")
    r.add_argument("config")
    r.add_argument("--out", type=Path, required=True)
    r.add_argument("--scenes", type=int, default=20)
    r.add_argument("--set", action="append", default=[], dest="overrides")
    s = sub.add_parser("score")
    s.add_argument("dir", type=Path)
    s.add_argument("--detectors", required=True)
    s.add_argument("--sets", type=Path)
    v = sub.add_parser("speed")
    v.add_argument("--video", type=Path)
    v.add_argument("--scenes-dir", type=Path)
    v.add_argument("--detectors", required=True)
    v.add_argument("--frames", type=int, default=40)
    args = p.parse_args(argv)
    if args.cmd == "render":
        n = render(args.config, args.out, args.scenes, args.overrides)
        print(f"rendered {n} scenes into {args.out}")
    elif args.cmd == "score":
        scores = [score_detector(d, args.dir, args.sets) for d in args.detectors.split(",")]
        print(_table(scores))
        best = choose_default(scores)
        print(f"\ndefault by the rule: {best.detector if best else 'none eligible'}")
    else:
        if (args.video is None) == (args.scenes_dir is None):
            p.error("give one of --video and --scenes-dir")
        for d in args.detectors.split(","):
            print(json.dumps(speed(d, args.video, args.scenes_dir, args.frames)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
