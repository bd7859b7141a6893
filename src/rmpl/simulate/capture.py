"""``rmpl simulate``: a recording of a rig with known everything.

:func:`simulate` writes into ``out/``:

- ``videos/<camera>.mp4``: one H.264 video per camera at its own frame rate, started at
  its own instant (:mod:`rmpl.simulate.video`);
- ``board/<camera>.mp4`` with ``board``: a calibration board carried through the volume,
  every camera filming the same instants (:mod:`rmpl.simulate.board`);
- ``truth/calibration.toml`` (the cameras, lenses included), ``truth/sync.json`` (each
  camera's offset, in ``rmpl sync``'s format), ``truth/poses.npz`` (every person's HALPE-26
  joints, metres, in ``rmpl run``'s format, on the reference camera's frames: the clock
  ``rmpl run --sync`` gives; from its frame 0 to the last instant any camera recorded),
  ``truth/people.json`` (identities, bodies, motion) and
  ``truth/projections/<camera>.npz`` (each joint's true pixel and whether another person
  hides it, per frame of that camera);
- ``simulate.json``: the settings and what is complete.

**Time.** The first camera is the reference. A camera's offset ``o`` (``--offsets``, in
its own frames) is the frame it records at the instant the reference records its frame 0,
so a camera with ``o = 3`` started 3 of its frames before the reference; the truth's
``sync.json`` holds ``o`` (minus the reference's own, converted through the frame rates).

**Resuming.** Each camera's video and projections are written whole (atomically); run the
same command again after an interruption and the cameras already written are kept. A
folder holding another simulation's settings is refused.

Shape glossary: ``S`` motion samples, ``P`` people, ``V`` cameras, ``T`` frames.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.simulate.rig import RigSpec, build_rig

__all__ = ["SimulateConfig", "Timing", "simulate", "timing_of", "parse_offsets"]

log = logging.getLogger(__name__)

FORMAT = "rmpl.simulate.v1"
#: Motion kinds a person can do (:mod:`rmpl.simulate.motion`).
ACTIVITIES = ("walk", "run", "turn", "bend")


@dataclass(frozen=True)
class SimulateConfig:
    """Everything a simulation depends on (the same settings give the same recording).

    Attributes:
        rig: the cameras (:class:`rmpl.simulate.rig.RigSpec`).
        people: moving people. bystander: one more person, standing still.
        motion: what the moving people do, person i ``motion[i % len(motion)]``.
        seconds: each camera's recording length.
        fps: frames per second, one value or one per camera.
        offsets: each camera's start offset in its own frames (one per camera), or
            ``"random:N"`` (uniform in -N..N, the first camera 0).
        board: a board spec (``rmpl calibrate --board``) to sweep through the volume, or None.
        board_seconds: the sweep's length.
        area: radius of the walking area, metres; None for the rig's (see :func:`_area`).
        crf: H.264 quality. seed: the random seed.
    """

    rig: RigSpec = field(default_factory=RigSpec)
    people: int = 2
    bystander: bool = False
    motion: tuple[str, ...] = ("walk",)
    seconds: float = 10.0
    fps: tuple[float, ...] = (30.0,)
    offsets: tuple[int, ...] | str = (0,)
    board: str | None = None
    board_seconds: float = 20.0
    area: float | None = None
    crf: int = 23
    seed: int = 0

    def to_json(self) -> dict:
        doc = asdict(self)
        doc["rig"] = asdict(self.rig)
        return doc

    @classmethod
    def from_args(cls, args) -> SimulateConfig:
        """From ``rmpl simulate``'s parsed options."""
        from rmpl.simulate.rig import PRESETS

        fov = args.fov if args.fov is not None else (None if args.focal else 65.0)
        dist = (tuple(args.distortion) + (0.0, 0.0))[:2]
        spec = RigSpec(args.rig, args.cameras, args.radius, args.height, fov, args.focal,
                       tuple(args.resolution), dist)  # fmt: skip
        cameras = args.cameras if args.rig in PRESETS else len(build_rig(spec))
        return cls(
            rig=spec,
            people=args.people,
            bystander=args.bystander,
            motion=tuple(m.strip() for m in args.motion.split(",") if m.strip()),
            seconds=args.seconds,
            fps=tuple(args.fps),
            offsets=parse_offsets(args.offsets, cameras),
            board=args.board,
            board_seconds=args.board_seconds,
            area=args.area,
            seed=args.seed,
        )

    def fingerprint(self) -> str:
        text = json.dumps(self.to_json(), sort_keys=True, default=list)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Timing:
    """When each camera records: its frame k is world time ``start[v] + k / fps[v]``."""

    fps: np.ndarray  # (V,)
    frames: np.ndarray  # (V,) frames recorded
    start: np.ndarray  # (V,) seconds
    offset_frames: np.ndarray  # (V,) as given, in each camera's frames

    @property
    def offsets_seconds(self) -> np.ndarray:
        """sync.json's offsets: how far each camera's clock is ahead of the reference's."""
        return self.start[0] - self.start

    def times(self, v: int) -> np.ndarray:
        return self.start[v] + np.arange(self.frames[v]) / self.fps[v]

    @property
    def span(self) -> tuple[float, float]:
        ends = self.start + (self.frames - 1) / self.fps
        return float(self.start.min()), float(ends.max())


def parse_offsets(text: str, cameras: int) -> tuple[int, ...] | str:
    """``--offsets``: integers, one per camera (``0,3,-5,11``), or ``random:N``."""
    text = text.strip()
    if text.startswith("random:"):
        try:
            n = int(text.split(":", 1)[1])
        except ValueError:
            n = -1
        if n < 0:
            raise InputError(None, "--offsets", "random:N with N >= 0 frames", text)
        return text
    try:
        values = tuple(int(x) for x in text.split(","))
    except ValueError:
        raise InputError(
            None, "--offsets", "whole frames, one per camera (0,3,-5,11) or random:N", text
        ) from None
    if len(values) == 1 and cameras > 1 and values[0] == 0:
        return (0,) * cameras
    if len(values) != cameras:
        raise InputError(None, "--offsets", f"{cameras} offsets, one per camera", len(values))
    return values


def timing_of(cfg: SimulateConfig, cameras: int, rng: np.random.Generator) -> Timing:
    """Each camera's frame rate, frames and start (see :class:`Timing`).

    Raises:
        InputError: a frame rate out of range, or an offset as long as the recording.
    """
    fps = (
        np.broadcast_to(np.asarray(cfg.fps, float), (cameras,)).copy()
        if len(cfg.fps) == 1
        else np.asarray(cfg.fps, float)
    )
    if len(fps) != cameras:
        raise InputError(None, "--fps", f"one frame rate or {cameras}, one per camera", len(fps))
    if not ((fps >= 5) & (fps <= 240)).all():
        raise InputError(None, "--fps", "frame rates of 5-240 frames/s", list(fps))
    if not 0.5 <= cfg.seconds <= 600:
        raise InputError(None, "--seconds", "a recording of 0.5-600 s", cfg.seconds)
    if isinstance(cfg.offsets, str):
        n = int(cfg.offsets.split(":")[1])
        off = rng.integers(-n, n + 1, cameras)
        off[0] = 0
    else:
        off = np.broadcast_to(np.asarray(cfg.offsets, int), (cameras,)).copy()
    frames = np.round(cfg.seconds * fps).astype(int)
    too_long = np.abs(off) / fps >= cfg.seconds / 2
    if too_long.any():
        v = int(np.flatnonzero(too_long)[0])
        raise InputError(
            None,
            "--offsets",
            f"offsets shorter than half the recording "
            f"({cfg.seconds:g} s, {frames[v]} frames of camera {v + 1}), so "
            "that the cameras share most of it",
            int(off[v]),
        )
    start = -off / fps
    return Timing(fps, frames, start - start[0], off)


def _area(cfg: SimulateConfig, rig) -> float:
    """The walking area's radius: given, or 45% of the nearest camera's horizontal
    distance to the centre, within 0.8-3 m."""
    if cfg.area is not None:
        if not 0.3 <= cfg.area <= 20:
            raise InputError(None, "--area", "a walking area radius of 0.3-20 m", cfg.area)
        return float(cfg.area)
    d = np.linalg.norm(rig.centers[:, :2], axis=1).min()
    return float(np.clip(0.45 * d, 0.8, 3.0))


def _check_people(cfg: SimulateConfig) -> None:
    if not 0 <= cfg.people <= 8:
        raise InputError(None, "--people", "0 to 8 moving people", cfg.people)
    if cfg.people == 0 and not cfg.bystander and cfg.board is None:
        raise InputError(None, "--people", "at least one person, a bystander or a board", 0)
    bad = [m for m in cfg.motion if m not in ACTIVITIES]
    if bad or not cfg.motion:
        raise InputError(None, "--motion", f"kinds among {', '.join(ACTIVITIES)}", bad)


def _manifest(out: Path, cfg: SimulateConfig) -> dict:
    """The folder's ``simulate.json``; a folder of other settings is refused."""
    path = out / "simulate.json"
    if path.exists():
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            raise InputError(path, None, "a readable simulate.json") from None
        if doc.get("fingerprint") != cfg.fingerprint():
            raise InputError(
                path,
                "settings",
                "the same settings as this command's (resume), or a new output folder",
                "another simulation",
            )
        return doc
    doc = {
        "format": FORMAT,
        "fingerprint": cfg.fingerprint(),
        "settings": cfg.to_json(),
        "complete": {},
    }
    _write_json(path, doc)
    return doc


def _write_json(path: Path, doc: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=1, default=_plain) + "\n", encoding="utf-8")


def _plain(x):
    if hasattr(x, "tolist"):
        return x.tolist()
    raise TypeError(type(x).__name__)


@dataclass
class World:
    """The people, sampled on the motion library's grid from the first camera's start."""

    rate: float
    t0: float
    vertices: np.ndarray  # (S, P, N, 3)
    joints: np.ndarray  # (S, P, 26, 3)
    faces: np.ndarray
    colors: np.ndarray  # (P, N, 3)
    plans: list
    light: object = None  # rmpl.synth.render.Lighting


def _world(cfg: SimulateConfig, rig, timing: Timing, rng, progress: bool) -> World:
    from tqdm import tqdm

    from rmpl.simulate.motion import load_motion_library
    from rmpl.simulate.people import plan_people, pose_people
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.render import random_outfits

    body = _body_model()
    bank, kinds = load_motion_library()
    rate = float(bank.fps[0])
    t0, t1 = timing.span
    samples = int(np.ceil((t1 - t0) * rate)) + 2
    P = cfg.people + int(cfg.bystander)
    phen = sample_phenotypes(P, rng, min_age=0.6)
    rest = body(body.identity_pose(P), phen).keypoints[:, :17].astype(float)
    legs = np.array([_legs(k) for k in rest])
    activities = [cfg.motion[i % len(cfg.motion)] for i in range(cfg.people)]
    plans = plan_people(
        bank, kinds, activities, cfg.bystander, samples, _area(cfg, rig), legs, phen, rng
    )
    pieces = sum(len(p.pieces) for p in plans)
    with tqdm(total=pieces, desc="bodies", unit="piece", disable=not progress) as bar:
        verts, joints = pose_people(plans, body, bank, samples, bar)
    colors = random_outfits(body.vertex_parts, P, rng)
    return World(rate, t0, verts, joints, body.faces, colors, plans)


def _legs(k: np.ndarray) -> float:
    from rmpl.anthropometry import leg_length

    return leg_length(k[None])


@functools.lru_cache(maxsize=1)
def _body_model():
    """anny with HALPE-26 joints, made once per process (it takes seconds)."""
    from rmpl.synth.body import BodyModel

    return BodyModel(joints="halpe26")


def write_rig_truth(out: Path, rig, timing: Timing) -> None:
    """``truth/calibration.toml`` and ``truth/sync.json`` (with or without people)."""
    from rmpl.calibration.sync import Sync, write_sync
    from rmpl.io.calibration import save_rig

    truth = out / "truth"
    truth.mkdir(parents=True, exist_ok=True)
    save_rig(rig, truth / "calibration.toml")
    V = len(rig)
    sync = Sync(
        list(rig.names),
        timing.fps,
        timing.offsets_seconds,
        np.ones(V),
        "3d-fine",
        np.zeros(V),
        np.zeros(V),
    )
    write_sync(sync, truth / "sync.json")


def write_truth(out: Path, timing: Timing, world: World, bank_clips) -> None:
    """``truth/poses.npz`` and ``truth/people.json``."""
    from rmpl.io.poses import Poses3D, save_poses
    from rmpl.simulate.people import at_times

    truth = out / "truth"
    t1 = timing.span[1]  # the reference's clock, as far as any camera recorded
    count = int(np.floor((t1 - timing.start[0]) * timing.fps[0] + 1e-6)) + 1
    times = timing.start[0] + np.arange(count) / timing.fps[0] - world.t0
    pts = at_times(world.joints, world.rate, times).astype(float)
    P = pts.shape[1]
    poses = Poses3D(
        pts,
        skeleton="halpe26",
        frames=np.arange(len(times)),
        fps=float(timing.fps[0]),
        person_ids=np.arange(P),
    )
    save_poses(poses, truth / "poses.npz")
    _write_json(truth / "people.json", {"people": [p.to_json(bank_clips) for p in world.plans]})


def _render_camera(
    out: Path, v: int, cam, timing: Timing, world: World, renderer, style, cfg, progress: bool
) -> None:
    """``videos/<cam>.mp4`` and ``truth/projections/<cam>.npz`` of camera ``v``."""
    from tqdm import tqdm

    from rmpl.simulate.people import at_times
    from rmpl.simulate.render import CameraView
    from rmpl.simulate.video import VideoWriter

    view = CameraView(cam, style)
    rng = np.random.default_rng([cfg.seed, v, 11])
    times = timing.times(v) - world.t0
    T, P = len(times), world.vertices.shape[1]
    uv = np.full((T, P, 26, 2), np.nan, np.float32)
    hidden = np.zeros((T, P, 26), bool)
    K, R, t = view.canvas_K[None, None], cam.R[None, None], cam.t[None, None]
    size = np.array(view.canvas_size)[None, None]
    W, H = cam.size
    with VideoWriter(out / "videos" / f"{cam.name}.mp4", timing.fps[v], cam.size, cfg.crf) as video:
        for k in tqdm(range(T), desc=f"render {cam.name}", unit="frame", disable=not progress):
            verts = at_times(world.vertices, world.rate, times[k : k + 1])
            images, ids = renderer.render_scene(
                verts, world.colors[None], K, R, t, size, lighting=[world.light], backgrounds=False
            )
            image, shown = view.frame(images[0], ids[0], rng)
            video.write(image)
            joints = at_times(world.joints, world.rate, times[k : k + 1])[0].astype(float)
            px = cam.project(joints)  # (P, 26, 2)
            x, y = np.rint(px[..., 0]).astype(int), np.rint(px[..., 1]).astype(int)
            inside = (x >= 0) & (x < W) & (y >= 0) & (y < H) & _in_front(cam, joints)
            who = np.where(inside, shown[y.clip(0, H - 1), x.clip(0, W - 1)], -1)
            hidden[k] = inside & (who >= 0) & (who != np.arange(P)[:, None])
            uv[k] = np.where(inside[..., None], px, np.nan)
    path = out / "truth" / "projections" / f"{cam.name}.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, uv=uv, hidden=hidden, frames=np.arange(T), fps=timing.fps[v])


def _in_front(cam, points: np.ndarray) -> np.ndarray:
    return (points @ cam.R.T + cam.t)[..., 2] > 0.1


def _people_videos(cfg, out: Path, rig, timing: Timing, rng, style, doc: dict, progress: bool):
    """The people's truth and each camera's video not yet written (resume)."""
    from rmpl.synth.render import Renderer, random_lighting

    todo = [v for v, cam in enumerate(rig) if not _done(out, cam.name)]
    if cfg.people + int(cfg.bystander) == 0:
        return
    if not todo and (out / "truth/poses.npz").exists():
        return
    world = _world(cfg, rig, timing, rng, progress)
    world.light = random_lighting(np.random.default_rng([cfg.seed, 5]))
    from rmpl.simulate.motion import load_motion_library

    write_truth(out, timing, world, load_motion_library()[0])
    with Renderer(world.faces, world.vertices.shape[2]) as renderer:
        for v in todo:
            _render_camera(out, v, rig[v], timing, world, renderer, style, cfg, progress)
            doc["complete"][rig[v].name] = True
            _write_json(out / "simulate.json", doc)


def simulate(cfg: SimulateConfig, out: str | Path, progress: bool = True) -> dict:
    """Simulate the capture ``cfg`` describes into ``out`` (see the module docstring).

    Returns:
        ``simulate.json``'s document.

    Raises:
        InputError: bad settings, or ``out`` holding another simulation.
    """
    from rmpl.simulate.render import room_style

    out = Path(out)
    rig = build_rig(cfg.rig)
    _check_people(cfg)
    rng = np.random.default_rng(cfg.seed)
    timing = timing_of(cfg, len(rig), rng)
    if cfg.board is not None:
        from rmpl.simulate.board import check_board

        check_board(cfg.board, rig, cfg.board_seconds)
    out.mkdir(parents=True, exist_ok=True)
    doc = _manifest(out, cfg)
    style = room_style(np.random.default_rng([cfg.seed, 7]), rig.centers)
    write_rig_truth(out, rig, timing)
    _people_videos(cfg, out, rig, timing, rng, style, doc, progress)
    if cfg.board is not None and not (out / "board" / "board.json").exists():
        from rmpl.simulate.board import sweep

        sweep(
            cfg.board,
            rig,
            out / "board",
            cfg.board_seconds,
            float(timing.fps.min()),
            style,
            np.random.default_rng([cfg.seed, 13]),
            cfg.crf,
            progress,
        )
    doc["rig"] = {
        "cameras": rig.names,
        "fps": timing.fps,
        "frames": timing.frames,
        "offset_frames": timing.offset_frames,
        "area_m": _area(cfg, rig),
    }
    doc["finished"] = True
    _write_json(out / "simulate.json", doc)
    return doc


def _done(out: Path, name: str) -> bool:
    return (out / "videos" / f"{name}.mp4").exists() and (
        out / "truth" / "projections" / f"{name}.npz"
    ).exists()
