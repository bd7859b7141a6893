"""The motion library of ``rmpl simulate``: real human motion shipped inside the package.

A few minutes of the CMU Graphics Lab motion capture (mocap.cs.cmu.edu), chosen by
:data:`CLIPS` and sorted into :data:`KINDS`, kept as a :class:`MotionBank` (anny's driver
rotations and the mocap's own COCO-17 joints, see
:func:`rmpl.synth.generate.sequences.build_motion_bank`) resampled to :data:`RATE` frames a
second. :func:`build_motion_library` makes ``data/motion.npz`` from a CMU folder;
:func:`load_motion_library` reads it (no external data needed); :func:`pick_segment` draws
the rows of a stretch of one kind.

What the kinds hold (the CMU subset in ``../shared/data/cmu_mocap``):

- ``walk``: straight walks across the capture volume, normal and slow, 2.5-5.6 s each,
  seven subjects.
- ``run``: straight runs, 1.0-1.4 s each (the runner crosses the volume), two subjects.
- turning has no clip of its own: the subset's turning walks are on uneven terrain (the
  feet up to 0.35 m above the floor, which a flat floor cannot show) or are jumps, so the
  simulator makes people turn by joining pieces of walking (:mod:`rmpl.simulate.people`).
- ``bend``: the subset has no clip labelled bending or picking up apart from 02_06 ("bend
  over, scoop up, rise, lift arm"); the rest is the nearest real motion: washing oneself
  (02_10: bending down to the legs and feet) and reaching up on tiptoe (13_10, 14_07).

Storage: each rotation as a unit quaternion, each frame's mid-hip, and each joint as an
offset from it, quantised to whole multiples of :data:`QUATERNION_STEP`, :data:`HIP_STEP`
and :data:`JOINT_STEP`, and kept as second differences along the rows (int16; int32 for
the mid-hip): smooth motion leaves small numbers, which the ``.npz``'s zip compresses well
(1.8 MB for the library, against 3.2 MB as compressed float16 arrays). Decoding is exact
up to the quantisation: at most 0.03 degrees per rotation and 0.25 mm per joint coordinate.

Shape glossary: ``N`` rows (frames of all segments back to back), ``K`` driven anny bones,
``G`` segments, ``C`` clips.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.synth.generate.sequences import MotionBank, build_motion_bank

__all__ = [
    "CLIPS",
    "KINDS",
    "LIBRARY",
    "RATE",
    "build_motion_library",
    "load_motion_library",
    "pick_segment",
]

log = logging.getLogger(__name__)

KINDS = ("walk", "run", "bend")

#: Frames per second of the library (the CMU clips' 120, every second frame).
RATE = 60.0

#: The shipped library.
LIBRARY = Path(__file__).parent / "data" / "motion.npz"

#: Quantisation of the unit quaternions, of the mid-hip (metres) and of the joints' offsets
#: from the mid-hip (metres).
QUATERNION_STEP = 1.0 / 4096
HIP_STEP = 1e-4
JOINT_STEP = 5e-4

#: CMU trial id -> kind, with the trial's description in the CMU index. A trial present as
#: ASF/AMC and as BVH is taken from the ASF/AMC (the original skeleton).
CLIPS: dict[str, str] = {
    "02_01": "walk",  # walk
    "02_02": "walk",  # walk
    "05_01": "walk",  # walk
    "06_01": "walk",  # walk
    "07_01": "walk",  # walk
    "07_04": "walk",  # slow walk
    "08_02": "walk",  # walk
    "08_04": "walk",  # slow walk
    "10_04": "walk",  # walk
    "12_01": "walk",  # walk
    "12_02": "walk",  # walk
    "02_03": "run",  # run/jog
    "09_01": "run",  # run
    "09_02": "run",  # run
    "09_03": "run",  # run
    "09_04": "run",  # run
    "09_05": "run",  # run
    "09_06": "run",  # run
    "09_07": "run",  # run
    "09_08": "run",  # run
    "09_09": "run",  # run
    "09_11": "run",  # run (09_10's conversion is broken, BROKEN_CLIPS)
    "02_06": "bend",  # bend over, scoop up, rise, lift arm
    "02_10": "bend",  # wash self
    "13_10": "bend",  # jump up to grab, reach for, tiptoe
    "14_07": "bend",  # jump up to grab, reach for, tiptoe
}

_FORMAT = "rmpl.simulate.motion.v1"
_INDEX = "cmu-mocap-index.tsv"
_PER_SEGMENT = ("start", "length", "first", "clip_index")
_PER_CLIP = ("clips", "subjects", "fps", "rest_dirs", "kinds", "descriptions")
_ENCODED = ("quaternions", "hips", "offsets", "quaternion_step", "hip_step", "joint_step")


def build_motion_library(cmu_root: str | Path, out_path: str | Path) -> Path:
    """Build the motion library from the CMU folder and write it atomically.

    Args:
        cmu_root: the CMU motion folder (``.asf``/``.amc`` and ``.bvh`` files below it, and
            its ``cmu-mocap-index.tsv``).
        out_path: the ``.npz`` to write (the shipped one is :data:`LIBRARY`).

    Returns:
        ``out_path``.

    Raises:
        InputError: a trial of :data:`CLIPS` or its description is missing from the folder.
    """
    cmu_root, out_path = Path(cmu_root), Path(out_path)
    subjects = sorted({trial.split("_")[0] for trial in CLIPS})
    bank = build_motion_bank(cmu_root, subjects=subjects)
    chosen = _chosen_clips(cmu_root, bank)
    bank = _resample(_only_clips(bank, chosen), RATE)
    trials = [Path(c).stem for c in bank.clips]
    descriptions = _descriptions(cmu_root, trials)
    arrays = {
        **{k: getattr(bank, k) for k in _PER_SEGMENT + _PER_CLIP[:4]},
        **_encode(bank.rotations, bank.joints),
        "kinds": np.array([CLIPS[t] for t in trials], str),
        "descriptions": np.array([descriptions[t] for t in trials], str),
    }
    with atomic_path(out_path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, format=np.array(_FORMAT), **arrays)
    log.info("motion library %s: %d clips, %d segments, %.1f s", out_path, len(trials),
             len(bank), (bank.length - 1).sum() / RATE)  # fmt: skip
    return out_path


def load_motion_library(path: str | Path | None = None) -> tuple[MotionBank, np.ndarray]:
    """The motion library: the shipped one (:data:`LIBRARY`) unless ``path`` is given.

    Read once per path and cached; the arrays are read-only.

    Returns:
        The bank (float32 rotation matrices (N, K, 3, 3), COCO-17 joints (N, 17, 3) metres z
        up, every clip at :data:`RATE`) and each segment's kind, one of :data:`KINDS`, (G,).

    Raises:
        InputError: the file is missing or is not a motion library.
    """
    return _load(Path(LIBRARY if path is None else path))


def pick_segment(
    bank: MotionBank, kinds: np.ndarray, kind: str, seconds: float, rng: np.random.Generator
) -> tuple[int, np.ndarray]:
    """The rows of ``seconds`` of one segment of ``kind``, from a random place in it.

    The segment is drawn among those of ``kind`` holding at least round(seconds * fps) + 1
    frames, in proportion to the number of places a window can start in it, and the start
    uniformly. When none is that long the longest one is played forward then backward
    (ping-pong) from a random place, as often as needed: the motion stays continuous.
    Either way there are exactly round(seconds * fps) + 1 rows, one per frame at the bank's
    rate.

    Args:
        bank, kinds: the library (:func:`load_motion_library`); kinds (G,).
        kind: one of :data:`KINDS`. seconds: duration, >= 0.

    Returns:
        (segment, rows of the bank, shape (T,) int64).
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    if not seconds >= 0:
        raise ValueError(f"seconds must be >= 0, got {seconds}")
    candidates = np.flatnonzero(np.asarray(kinds) == kind)
    if not len(candidates):
        raise ValueError(f"the motion library has no segment of kind {kind!r}")
    fps = bank.fps[bank.clip_index[candidates]]
    frames = np.round(seconds * fps).astype(np.int64) + 1  # per candidate, (G',)
    places = bank.length[candidates] - frames + 1
    if (places > 0).any():
        p = np.maximum(places, 0).astype(float)
        i = int(rng.choice(len(candidates), p=p / p.sum()))
        steps = int(rng.integers(0, places[i])) + np.arange(frames[i])
    else:
        i = int(np.argmax(bank.length[candidates]))
        steps = _ping_pong(int(bank.length[candidates[i]]), int(frames[i]), rng)
    seg = int(candidates[i])
    return seg, bank.start[seg] + steps


def _ping_pong(length: int, frames: int, rng: np.random.Generator) -> np.ndarray:
    """``frames`` steps through 0 .. length - 1 and back, from a random phase, (frames,)."""
    period = max(2 * (length - 1), 1)
    phase = int(rng.integers(0, period)) + np.arange(frames)
    return (length - 1) - np.abs(phase % period - (length - 1))


def _chosen_clips(cmu_root: Path, bank: MotionBank) -> np.ndarray:
    """Indices into ``bank.clips`` of the :data:`CLIPS` trials, the ASF/AMC one if a trial
    comes in both formats, in the bank's order."""
    by_trial: dict[str, int] = {}
    for c, clip in enumerate(bank.clips):
        trial = Path(str(clip)).stem
        if trial in CLIPS and (trial not in by_trial or str(clip).endswith(".amc")):
            by_trial[trial] = c
    missing = [t for t in CLIPS if t not in by_trial or not (bank.clip_index == by_trial[t]).any()]
    if missing:
        raise InputError(cmu_root, missing[0], "a CMU trial with clean motion", "missing")
    return np.sort(list(by_trial.values()))


def _only_clips(bank: MotionBank, clips: np.ndarray) -> MotionBank:
    """The segments of ``clips`` (indices into ``bank.clips``), the per-clip arrays cut to
    those clips and ``clip_index`` renumbered."""
    sub = bank.select(np.isin(bank.clip_index, clips))
    renumber = np.full(len(bank.clips), -1, np.int64)
    renumber[clips] = np.arange(len(clips))
    return MotionBank(
        sub.rotations, sub.joints, sub.start, sub.length, sub.first, renumber[sub.clip_index],
        bank.clips[clips], bank.subjects[clips], bank.fps[clips], bank.rest_dirs[clips],
    )  # fmt: skip


def _resample(bank: MotionBank, rate: float) -> MotionBank:
    """Every k-th frame of each clip (k = its fps / ``rate``, a whole number), on the clip's
    own grid of frames 0, k, 2k, ...; segments left with fewer than 2 frames are dropped."""
    step = np.round(bank.fps / rate).astype(np.int64)  # (C,)
    if (step < 1).any() or not np.allclose(bank.fps / step, rate):
        raise InputError(None, "fps", f"clips at a whole multiple of {rate:g} fps", bank.fps)
    rows, length, first, keep = [], [], [], []
    for g, (a, n, f) in enumerate(zip(bank.start, bank.length, bank.first, strict=True)):
        k = int(step[bank.clip_index[g]])
        skip = -int(f) % k  # the first frame on the clip's grid
        r = np.arange(a + skip, a + n, k)
        if len(r) >= 2:
            rows.append(r)
            length.append(len(r))
            first.append((f + skip) // k)
            keep.append(g)
    length = np.array(length, np.int64)
    rows = np.concatenate(rows)
    return MotionBank(
        bank.rotations[rows], bank.joints[rows], np.cumsum(length) - length, length,
        np.array(first, np.int64), bank.clip_index[keep], bank.clips, bank.subjects,
        np.full(len(bank.clips), rate), bank.rest_dirs,
    )  # fmt: skip


def _descriptions(cmu_root: Path, trials: list[str]) -> dict[str, str]:
    """Each trial's description in the folder's CMU index (``cmu-mocap-index.tsv``)."""
    path = cmu_root / _INDEX
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as e:
        raise InputError(path, None, "the CMU trial index", e) from None
    table = dict(line.split("\t")[:2] for line in lines if line.count("\t") >= 1)
    missing = [t for t in trials if t not in table]
    if missing:
        raise InputError(path, missing[0], "the trial's description", "missing")
    return {t: table[t].strip() for t in trials}


def _encode(rotations: np.ndarray, joints: np.ndarray) -> dict[str, np.ndarray]:
    """Rotations (N, K, 3, 3) and joints (N, 17, 3) as the library stores them (see the
    module docstring)."""
    from scipy.spatial.transform import Rotation

    N, K = rotations.shape[:2]
    q = Rotation.from_matrix(rotations.reshape(-1, 3, 3).astype(float)).as_quat()
    q = q.reshape(N, K, 4)
    # q and -q are one rotation: flip signs so that consecutive rows agree (small steps).
    flip = np.where(np.sum(q[1:] * q[:-1], axis=-1, keepdims=True) < 0, -1.0, 1.0)
    q[1:] *= np.cumprod(flip, axis=0)  # (N - 1, K, 1): every row agrees with the one before
    hips = np.round(joints[:, 11:13].astype(float).mean(axis=1) / HIP_STEP)  # (N, 3) mid-hip
    offsets = joints - hips[:, None] * HIP_STEP
    return {
        "quaternions": _differences(q / QUATERNION_STEP, np.int16),
        "hips": _differences(hips, np.int32),
        "offsets": _differences(offsets / JOINT_STEP, np.int16),
        "quaternion_step": np.float64(QUATERNION_STEP),
        "hip_step": np.float64(HIP_STEP),
        "joint_step": np.float64(JOINT_STEP),
    }


def _differences(x: np.ndarray, dtype: type) -> np.ndarray:
    """Second differences along the rows of ``x`` rounded to integers (the first two rows
    against zeros), as ``dtype``; :func:`_sums` undoes them."""
    x = np.round(x).astype(np.int64)
    d = np.diff(x, n=2, axis=0, prepend=np.zeros((2, *x.shape[1:]), np.int64))
    if np.abs(d).max(initial=0) > np.iinfo(dtype).max:
        raise ValueError(f"motion too fast between rows for the library's {dtype.__name__}")
    return d.astype(dtype)


def _sums(d: np.ndarray) -> np.ndarray:
    return np.cumsum(np.cumsum(d, axis=0, dtype=np.int64), axis=0)


def _decode(z) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, K, 3, 3) float32 and joints (N, 17, 3) float32 from a library file."""
    from scipy.spatial.transform import Rotation

    q = _sums(z["quaternions"]) * float(z["quaternion_step"])
    N, K = q.shape[:2]
    R = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(N, K, 3, 3)
    hips = _sums(z["hips"]) * float(z["hip_step"])  # (N, 3)
    joints = hips[:, None] + _sums(z["offsets"]) * float(z["joint_step"])
    return R.astype(np.float32), joints.astype(np.float32)


@functools.lru_cache(maxsize=4)
def _load(path: Path) -> tuple[MotionBank, np.ndarray]:
    what = "a motion library .npz (rmpl.simulate.motion.build_motion_library)"
    if not path.is_file():
        raise InputError(path, None, what, "no such file")
    try:
        with np.load(path, allow_pickle=False) as z:
            got = str(z["format"]) if "format" in z.files else "none"
            if got != _FORMAT:
                raise InputError(path, "format", f"{_FORMAT!r} ({what})", got)
            missing = [k for k in _PER_SEGMENT + _PER_CLIP + _ENCODED if k not in z.files]
            if missing:
                raise InputError(path, missing[0], "an array of a motion library", "missing")
            rotations, joints = _decode(z)
            arrays = {k: z[k] for k in _PER_SEGMENT + _PER_CLIP}
    except (OSError, ValueError, EOFError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(path, None, what, e) from None
    unknown = sorted(set(arrays["kinds"].tolist()) - set(KINDS))
    if unknown or len(arrays["kinds"]) != len(arrays["clips"]):
        raise InputError(path, "kinds", f"one of {KINDS} per clip", unknown or arrays["kinds"])
    bank = MotionBank(rotations, joints, **{k: arrays[k] for k in _PER_SEGMENT + _PER_CLIP[:4]})
    kinds = arrays["kinds"][bank.clip_index]
    for a in (*(getattr(bank, k) for k in _PER_SEGMENT + _PER_CLIP[:4]), rotations, joints, kinds):
        a.flags.writeable = False  # shared by every caller of the cache
    return bank, kinds
