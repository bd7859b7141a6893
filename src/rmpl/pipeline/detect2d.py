"""2D keypoints from synchronised videos or image folders, one or several people per view.

Each view is run through a :class:`rmpl.synth.detect.Detector` (the protocol the MHP
generator also uses), so any detector that follows it plugs in: a single-person one, whose
(B, J, 2) output gets a people axis of 1, or a :class:`rmpl.synth.detect.MultiPersonDetector`
with (B, N, J, 2). :data:`DETECTORS` names the ones ``rmpl run --detector`` offers:

- ``movenet-blazepose`` (the default, :data:`DEFAULT_DETECTOR`): Google's MoveNet
  MultiPose Lightning (shipped with rmpl, Apache-2.0, run on LiteRT) finds up to 6 people
  per frame, and BlazePose's full landmark network draws each of them in a crop, feet
  included, followed from frame to frame
  (:class:`rmpl.synth.detect_movenet.MoveNetBlazePose`); frames of a view are fed in order.
- ``movenet-blazepose-static``: the same, every frame detected afresh.
- ``movenet-blazepose-fast``: the same, MoveNet run every 5th frame while everyone is
  followed (at once where someone is lost): about half the CPU time per frame, a person
  who walks in found up to 4 frames late.
- ``movenet``: MoveNet alone, COCO-17 (no feet), every frame afresh.
- ``blazepose-multi``: BlazePose's own person detector and landmark network (shipped in
  the ``mediapipe==0.10.14`` wheel) for up to 4 people per frame, each followed from frame
  to frame (:class:`rmpl.synth.detect_multi.BlazePoseMulti`; the default before
  ``movenet-blazepose``).
- ``blazepose-multi-static``: the same, every frame detected afresh (slower).
- ``mediapipe``: MediaPipe's legacy ``Pose`` solution, one person per frame and view,
  every frame afresh, as in the training data of the shipped lifter.

Videos are read with OpenCV (``cv2``, which comes with mediapipe); nothing is downloaded.
Install them (and LiteRT, ``ai-edge-litert``, for MoveNet) with ``pip install 'rmpl[detect]'``.
With ``workers`` > 1 the cameras are detected in parallel on a local Ray instance.

The result is a :class:`rmpl.io.keypoints.Keypoints2D` with ``P`` = the most people any
view had in a frame (at least 1; a person's index in one view says nothing about the same
index in another view or, for a detector that does not follow people, another frame),
the views named after the files (or folders) without their suffix, frames numbered from 0
and, for videos, the videos' frame rate. Its joints are HALPE-26 when the detector's joint
set has COCO-17 and feet, neck, head top or mid-hip (BlazePose-33: its heels, and its foot
index in the big-toe slot, :func:`rmpl.skeleton.embed`; the HALPE-26 joints it lacks are
missing), else COCO-17 (:func:`rmpl.io.keypoints.richest`).

Every input is checked before any detection runs, and bad input raises one
:class:`rmpl.errors.InputError` naming the file: a video OpenCV cannot open or decode,
videos of different frame counts or frame rates (both are stated), an image folder with no
image, image folders of different lengths, an unreadable image. A view in which nobody is
found in any frame is named in a warning; nobody found in any view is an InputError.

Detection is resumable: with ``cache_dir``, each finished view is saved there
(``<index>_<view>.npz``) together with a fingerprint of its input (file names, sizes,
modification times) and of the detector (its name and people per frame), and a later call
with the same input and detector reuses it; one- and multi-person results never mix. A
view saved in COCO-17 beside views detected in HALPE-26 is placed in HALPE-26 (its extra
joints missing).

Shape glossary: ``T`` frames, ``V`` views, ``P`` people slots, ``N`` people one detector
call returns per image, ``J`` joints (17 or 26).
"""

from __future__ import annotations

import functools
import json
import logging
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.io.keypoints import Keypoints2D
from rmpl.skeleton import BY_COUNT

__all__ = [
    "IMAGE_SUFFIXES",
    "VideoInfo",
    "probe_video",
    "check_videos",
    "list_images",
    "check_image_folders",
    "input_fingerprint",
    "view_names",
    "video_frames",
    "image_frames",
    "detect_videos",
    "detect_images",
    "DETECTORS",
    "DEFAULT_DETECTOR",
]

log = logging.getLogger(__name__)

#: Files of an image folder that are read as frames (case-insensitive).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
_DIGITS = re.compile(r"(\d+)")


def _mediapipe(**kwargs):
    from rmpl.synth.detect import MediaPipeDetector

    return MediaPipeDetector(**kwargs)


def _blazepose_multi(**kwargs):
    from rmpl.synth.detect_multi import BlazePoseMulti

    return BlazePoseMulti(**kwargs)


def _movenet(**kwargs):
    from rmpl.synth.detect_movenet import MoveNet

    return MoveNet(**kwargs)


def _movenet_blazepose(**kwargs):
    from rmpl.synth.detect_movenet import MoveNetBlazePose

    return MoveNetBlazePose(**kwargs)


#: Detector factories by name, for ``rmpl run --detector`` (imported when called).
DETECTORS: dict[str, Callable[[], object]] = {
    "blazepose-multi": _blazepose_multi,
    "blazepose-multi-static": functools.partial(_blazepose_multi, track=False),
    "mediapipe": _mediapipe,
    "movenet": _movenet,
    "movenet-blazepose": _movenet_blazepose,
    "movenet-blazepose-static": functools.partial(_movenet_blazepose, track=False),
    "movenet-blazepose-fast": functools.partial(_movenet_blazepose, detect_every=5),
}
#: The detector of ``rmpl run --videos/--images``, chosen by measurement
#: (``rmpl.benchmarks.bench_detect``; docs/results.md).
DEFAULT_DETECTOR = "blazepose-multi"


@dataclass(frozen=True)
class VideoInfo:
    """What OpenCV says about one video.

    Attributes:
        path: the file.
        num_frames: frames in the video.
        fps: frames per second.
        size: (width, height), pixels.
    """

    path: Path
    num_frames: int
    fps: float
    size: tuple[int, int]


def _cv2():
    try:
        import cv2
    except ImportError as e:
        raise ImportError(
            "reading videos and images needs OpenCV: pip install 'rmpl[detect]'"
        ) from e
    return cv2


def probe_video(path: str | Path) -> VideoInfo:
    """Open a video, decode its first frame and read its length and frame rate.

    Raises:
        InputError: no such file, not a video OpenCV can decode, no frames or no frame rate.
    """
    cv2 = _cv2()
    path = Path(path)
    if not path.is_file():
        raise InputError(path, None, "an existing video file", "no such file")
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise InputError(path, None, "a video file OpenCV can open", "unreadable")
        ok, frame = cap.read()
        if not ok or frame is None:
            raise InputError(path, None, "a video with at least one decodable frame", "none")
        fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        if count <= 0:  # some containers do not say: count by decoding
            count = 1
            while cap.grab():
                count += 1
    finally:
        cap.release()
    if not np.isfinite(fps) or fps <= 0:
        raise InputError(path, "fps", "a video with a frame rate", fps)
    h, w = frame.shape[:2]
    return VideoInfo(path, count, fps, (int(w), int(h)))


def check_videos(paths: Sequence[str | Path], synchronised: bool = True) -> list[VideoInfo]:
    """Probe every video; with ``synchronised``, check they have the same frame count and
    frame rate. Without, videos of different lengths or rates (cameras not started
    together, phones at other rates) are accepted with one warning: ``rmpl sync`` finds
    their offsets and ``rmpl run --sync`` puts them on one clock.

    Raises:
        InputError: naming the offending file, with both counts or both rates.
    """
    if not paths:
        raise InputError(None, "videos", "at least one video", "none")
    infos = [probe_video(p) for p in paths]
    first = infos[0]
    for info in infos[1:]:
        if info.num_frames != first.num_frames and synchronised:
            raise InputError(
                info.path,
                "frames",
                f"{first.num_frames} frames like {first.path} (synchronised videos; else "
                "--sync with rmpl sync's offsets)",
                f"{info.num_frames} frames",
            )
        if abs(info.fps - first.fps) > 1e-3 * first.fps and synchronised:
            raise InputError(
                info.path,
                "fps",
                f"{first.fps:g} frames/s like {first.path} (synchronised videos; else "
                "--sync with rmpl sync's offsets)",
                f"{info.fps:g} frames/s",
            )
    if not synchronised and not _same_clock(infos):
        log.warning(
            "the videos differ in length or frame rate (%s): they were not started together "
            "or not filmed at one rate; put them on one clock with rmpl sync and --sync",
            ", ".join(f"{i.path.name} {i.num_frames} frames at {i.fps:g}/s" for i in infos),
        )
    return infos


def _same_clock(infos: list[VideoInfo]) -> bool:
    first = infos[0]
    return all(
        i.num_frames == first.num_frames and abs(i.fps - first.fps) <= 1e-3 * first.fps
        for i in infos
    )


def _natural_key(path: Path) -> tuple:
    return tuple(int(s) if s.isdigit() else s for s in _DIGITS.split(path.name.lower()))


def list_images(folder: str | Path) -> list[Path]:
    """The image files of a folder (:data:`IMAGE_SUFFIXES`), in natural name order
    (``frame2.png`` before ``frame10.png``).

    Raises:
        InputError: no such folder, or no image in it.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, None, "a folder of images", "no such folder")
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    if not files:
        raise InputError(
            folder, None, f"a folder with image files ({', '.join(IMAGE_SUFFIXES)})", "none"
        )
    return sorted(files, key=_natural_key)


def check_image_folders(folders: Sequence[str | Path]) -> list[list[Path]]:
    """The images of each folder, checked to be non-empty, of equal length and readable by
    OpenCV (from their headers).

    Raises:
        InputError: naming the folder with both lengths, or the unreadable file.
    """
    if not folders:
        raise InputError(None, "images", "at least one image folder", "none")
    cv2 = _cv2()
    lists = [list_images(f) for f in folders]
    for files in lists:
        for f in files:
            if not cv2.haveImageReader(str(f)):
                raise InputError(f, None, "an image file OpenCV can read", "unreadable")
    for folder, files in zip(folders[1:], lists[1:], strict=True):
        if len(files) != len(lists[0]):
            raise InputError(
                folder,
                "frames",
                f"{len(lists[0])} images like {folders[0]} (one image per frame)",
                f"{len(files)} images",
            )
    return lists


def view_names(paths: Sequence[str | Path]) -> list[str]:
    """View names from file or folder names without suffix; made distinct when they clash.

    >>> view_names(["a/cam1.mp4", "b/cam2.mp4"])
    ['cam1', 'cam2']
    >>> view_names(["a/cam.mp4", "b/cam.mp4"])
    ['a_cam', 'b_cam']
    """
    paths = [Path(p) for p in paths]
    names = [p.stem if p.suffix else p.name for p in paths]
    if len(set(names)) == len(names):
        return names
    names = [f"{p.parent.name}_{n}" for p, n in zip(paths, names, strict=True)]
    if len(set(names)) == len(names):
        return names
    return [f"view{i}" for i in range(len(paths))]


def _stat(path: Path) -> dict:
    st = path.stat()
    return {"path": str(path.resolve()), "size": st.st_size, "mtime_ns": st.st_mtime_ns}


def input_fingerprint(paths: Sequence[str | Path], kind: str) -> list:
    """What identifies an input: per view, its files' absolute names, sizes and mtimes.

    Args:
        paths: videos (``kind="videos"``) or image folders (``kind="images"``).

    Returns:
        A JSON-serialisable list, one entry per view.
    """
    if kind == "videos":
        return [_stat(Path(p)) for p in paths]
    if kind == "images":
        return [[_stat(f) for f in list_images(d)] for d in paths]
    raise ValueError(f"kind must be 'videos' or 'images', got {kind!r}")


# --------------------------------------------------------------------------- detection


def _make_detector(detector):
    """(detector, whether we own it and must close it)."""
    if detector is None:
        detector = DEFAULT_DETECTOR
    if isinstance(detector, str):
        if detector not in DETECTORS:
            raise ValueError(f"detector must be one of {sorted(DETECTORS)}, got {detector!r}")
        return DETECTORS[detector](), True
    return detector, False


def _output_joints(detector, kp: np.ndarray, sc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A detector's (*, J, 2), (*, J) in the richest joint set it supports: HALPE-26 (by
    name, :func:`rmpl.skeleton.embed`) when its joints include COCO-17 and any of the nine
    extra ones, else COCO-17."""
    from rmpl.io.keypoints import richest
    from rmpl.skeleton import to_joint_set

    name = detector.skeleton.name
    return to_joint_set(kp, sc, name, richest(name))


def _joint_set(num_joints: int) -> str:
    """The joint set of :func:`_output_joints`' results by their number of joints."""
    return BY_COUNT[num_joints]


def _detect_stream(
    frames: Iterator[np.ndarray], num_frames: int, detector, batch: int, desc: str, progress
) -> tuple[np.ndarray, np.ndarray]:
    """Run the detector over one view's RGB frames in order, ``batch`` at a time:
    keypoints (T, N, J, 2), scores (T, N, J). A detector that follows people is reset
    first."""
    from tqdm import tqdm

    from rmpl.synth.detect import with_people_axis

    reset = getattr(detector, "reset", None)
    if reset is not None:
        reset()
    kps, scs, chunk = [], [], []

    def run(bar) -> None:
        kp, sc = with_people_axis(detector, *detector(chunk), len(chunk))
        kps.append(kp)
        scs.append(sc)
        bar.update(len(chunk))

    with tqdm(total=num_frames, desc=desc, unit="frame", disable=not progress) as bar:
        for image in frames:
            chunk.append(image)
            if len(chunk) == batch:
                run(bar)
                chunk = []
        if chunk:
            run(bar)
    N = max(k.shape[1] for k in kps)  # a detector may return fewer slots in some calls
    kp = np.concatenate([_pad_people(k, N) for k in kps])
    sc = np.concatenate([_pad_people(s, N) for s in scs])
    return _output_joints(detector, kp, sc)


def _pad_people(a: np.ndarray, N: int) -> np.ndarray:
    """(T, n, ...) -> (T, N, ...): empty slots appended (NaN keypoints, zero scores)."""
    if a.shape[1] == N:
        return a
    fill = np.nan if a.ndim == 4 else 0.0
    pad = np.full((a.shape[0], N - a.shape[1], *a.shape[2:]), fill)
    return np.concatenate([a, pad], axis=1)


def video_frames(info: VideoInfo) -> Iterator[np.ndarray]:
    """The frames of a probed video, RGB uint8 (H, W, 3); InputError if it ends early."""
    cv2 = _cv2()
    cap = cv2.VideoCapture(str(info.path))
    try:
        for t in range(info.num_frames):
            ok, frame = cap.read()
            if not ok or frame is None:
                raise InputError(
                    info.path,
                    "frames",
                    f"{info.num_frames} decodable frames, as the video's header says",
                    f"only {t}",
                )
            yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
    finally:
        cap.release()


def image_frames(files: list[Path]) -> Iterator[np.ndarray]:
    """Read images as RGB uint8 (H, W, 3); InputError naming an unreadable file."""
    cv2 = _cv2()
    for f in files:
        image = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if image is None:
            raise InputError(f, None, "an image file OpenCV can read", "unreadable")
        yield cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _cached_view(path: Path, stamp: str) -> tuple[np.ndarray, np.ndarray] | None:
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["stamp"]) != stamp or data["keypoints"].ndim != 4:
                return None
            if data["keypoints"].shape[-2] not in (17, 26):
                return None
            return data["keypoints"], data["scores"]
    except (OSError, KeyError, ValueError):
        log.warning("ignoring an unreadable detection cache %s", path)
        return None


def _save_view(path: Path, stamp: str, kp: np.ndarray, sc: np.ndarray) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, stamp=np.array(stamp), keypoints=kp, scores=sc)


def _detector_stamp(detector) -> dict:
    """What identifies a detector's results: its name and, for an instance, its people per
    image (a name from :data:`DETECTORS` fixes both)."""
    if detector is None:
        detector = DEFAULT_DETECTOR
    if isinstance(detector, str):
        return {"detector": detector}
    from rmpl.synth.detect import max_people

    return {"detector": str(getattr(detector, "name", "?")), "people": max_people(detector)}


def _detect_views(
    names: list[str],
    sources: Sequence[str | Path],
    fingerprint: list,
    num_frames: int | list[int],
    frames_of: Callable[[int], Iterator[np.ndarray]],
    detector,
    batch: int,
    cache_dir: str | Path | None,
    progress: bool,
    workers: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Detect every view (or reuse its cache): (T, V, P, J, 2), (T, V, P, J), and the joint
    set's name; ``num_frames`` is one count or one per view (T is the largest: a shorter
    view ends in empty frames). With ``workers`` > 1 the views to detect run in parallel on
    Ray."""
    if isinstance(num_frames, int):
        num_frames = [num_frames] * len(names)
    kps: list = [None] * len(names)
    scs: list = [None] * len(names)
    todo = []
    for v, name in enumerate(names):
        cache = None if cache_dir is None else Path(cache_dir) / f"{v:02d}_{name}.npz"
        stamp = json.dumps({"input": fingerprint[v], **_detector_stamp(detector)})
        hit = None if cache is None else _cached_view(cache, stamp)
        if hit is not None and hit[0].shape[-2] == 17:  # made before detectors gave feet
            log.warning(
                "view %s: reusing COCO-17 detections from %s (made before the detectors "
                "gave feet); delete it to detect the heels too", name, cache,
            )  # fmt: skip
        if hit is not None and hit[0].shape[0] == num_frames[v]:
            log.info("view %s: reusing detections from %s", name, cache)
            kps[v], scs[v] = hit
        else:
            todo.append((v, cache, stamp))
    run = _detect_on_ray if workers > 1 and len(todo) > 1 else _detect_here
    for (v, cache, stamp), (kp, sc) in zip(
        todo,
        run(todo, names, num_frames, frames_of, detector, batch, progress, workers),
        strict=True,
    ):
        if cache is not None:
            _save_view(cache, stamp, kp, sc)
        kps[v], scs[v] = kp, sc
    from rmpl.skeleton import embed, embed_scores

    skeleton = _joint_set(max(k.shape[-2] for k in kps))
    for v, k in enumerate(kps):  # a COCO-17 view saved beside HALPE-26 ones
        if _joint_set(k.shape[-2]) != skeleton:
            kps[v], scs[v] = embed(k, "coco17", skeleton), embed_scores(scs[v], "coco17", skeleton)
    return (*_stack_views(kps, scs, sources), skeleton)


def _detect_here(todo, names, num_frames, frames_of, detector, batch, progress, workers):
    """The views of ``todo`` one after the other, in this process: yields (kp, sc)."""
    det, owned = None, False
    try:
        for v, _, _ in todo:
            if det is None:
                det, owned = _make_detector(detector)
            yield _detect_stream(
                frames_of(v), num_frames[v], det, batch, f"detect {names[v]}", progress
            )
    finally:
        if owned:
            det.close()


def _detect_one_view(frames_of, v: int, num_frames: int, detector: str, batch: int):
    """View ``v`` with a detector of its own (a Ray task's body)."""
    det, _ = _make_detector(detector)
    try:
        return _detect_stream(frames_of(v), num_frames, det, batch, "", False)
    finally:
        det.close()


def _detect_on_ray(todo, names, num_frames, frames_of, detector, batch, progress, workers):
    """The views of ``todo`` as Ray tasks, ``workers`` at a time, each with its own detector
    (so a name of :data:`DETECTORS`, not an instance): the same results as one after the
    other. Ray is started here, a new instance on this machine, when this process has none
    yet (``address="local"``: never another cluster)."""
    if detector is not None and not isinstance(detector, str):
        raise ValueError("detecting views in parallel needs a detector name, not an instance")
    try:
        import ray
    except ImportError as e:
        raise ImportError("detecting views in parallel needs Ray: pip install 'rmpl[ray]'") from e
    from tqdm import tqdm

    if not ray.is_initialized():
        ray.init(address="local", num_cpus=workers, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1)(_detect_one_view)
    name = detector or DEFAULT_DETECTOR
    refs = [task.remote(frames_of, v, num_frames[v], name, batch) for v, _, _ in todo]
    with tqdm(total=len(refs), desc="detect views", unit="view", disable=not progress) as bar:
        for ref in refs:  # in order, each saved to the cache as soon as it is back
            result = ray.get(ref)
            bar.update(1)
            yield result


def _stack_views(
    kps: list[np.ndarray], scs: list[np.ndarray], sources: Sequence[str | Path]
) -> tuple[np.ndarray, np.ndarray]:
    """Per-view (T, N_v, J, 2) and (T, N_v, J) -> (T, V, P, J, 2), (T, V, P, J), with P the
    most slots any view used (at least 1). Warns about a view where nobody was found.

    Raises:
        InputError: nobody found in any frame of any view.
    """
    seen = [(s > 0).any(axis=-1) for s in scs]  # per view (T, N_v): slot used in a frame
    for source, used in zip(sources, seen, strict=True):
        if not used.any():
            log.warning("nobody was detected in any of the %d frames of %s", len(used), source)
    if not any(used.any() for used in seen):
        raise InputError(
            ", ".join(map(str, sources)),
            "people",
            "at least one person detected in some frame of some view",
            "nobody in any frame",
        )
    # Slots past the last one used in any frame of any view are dropped.
    P = max(1, *(int(np.flatnonzero(used.any(axis=0)).max(initial=-1)) + 1 for used in seen))
    T = max(len(k) for k in kps)  # a shorter view (videos not started together) ends empty
    kps = [np.concatenate([k, np.full((T - len(k), *k.shape[1:]), np.nan)]) for k in kps]
    scs = [np.concatenate([s, np.zeros((T - len(s), *s.shape[1:]))]) for s in scs]
    kp = np.stack([_pad_people(k, max(P, k.shape[1]))[:, :P] for k in kps], axis=1)
    sc = np.stack([_pad_people(s, max(P, s.shape[1]))[:, :P] for s in scs], axis=1)
    return kp, sc


def detect_videos(
    paths: Sequence[str | Path],
    detector=None,
    *,
    batch: int = 8,
    cache_dir: str | Path | None = None,
    progress: bool = True,
    workers: int = 1,
) -> Keypoints2D:
    """Detect people in every frame of each of several synchronised videos.

    Args:
        paths: one video per camera, any format OpenCV (FFmpeg) decodes.
        detector: a :class:`rmpl.synth.detect.Detector` (one person per image, or a
            :class:`~rmpl.synth.detect.MultiPersonDetector`), a name from
            :data:`DETECTORS`, or None for :data:`DEFAULT_DETECTOR`. A detector passed in
            is not closed (but is reset before each view, if it can be).
        batch: frames handed to the detector at a time.
        cache_dir: folder for per-view results, to resume an interrupted run (optional).
        progress: show a progress bar per view.
        workers: views detected at once; above 1 they run as Ray tasks on this machine
            (``rmpl[ray]``; ``ray.init`` is called only then, and only if Ray is not
            running), each with its own detector, so ``detector`` must be a name; the
            results are those of one view after the other.

    Returns:
        Keypoints (T, V, P, J, 2) in pixels, scores (T, V, P, J), COCO-17 or HALPE-26 (see
        the module docstring); views named after the files, frames 0..T-1, the videos'
        frame rate.

    Raises:
        InputError: bad input (see the module docstring), before any detection runs; or
            nobody found in any frame of any video.
    """
    infos = check_videos(paths, synchronised=False)
    names = view_names(paths)
    T = max(i.num_frames for i in infos)
    kp, sc, skeleton = _detect_views(
        names,
        paths,
        input_fingerprint(paths, "videos"),
        [i.num_frames for i in infos],
        lambda v: video_frames(infos[v]),
        detector,
        batch,
        cache_dir,
        progress,
        workers,
    )
    return Keypoints2D(kp, sc, skeleton, names, np.arange(T), infos[0].fps)


def detect_images(
    folders: Sequence[str | Path],
    detector=None,
    *,
    fps: float | None = None,
    batch: int = 8,
    cache_dir: str | Path | None = None,
    progress: bool = True,
    workers: int = 1,
) -> Keypoints2D:
    """Detect people in every image of each of several folders of synchronised frames.

    Image ``i`` (in natural name order) of every folder is frame ``i``.

    Args:
        folders: one folder of images per camera, all of the same length.
        detector, batch, cache_dir, progress, workers: as in :func:`detect_videos`.
        fps: frame rate to record, if known.

    Returns:
        Keypoints (T, V, P, J, 2) in pixels, scores (T, V, P, J), COCO-17 or HALPE-26 (see
        the module docstring); views named after the folders, frames 0..T-1.

    Raises:
        InputError: bad input (see the module docstring), before any detection runs (an
            image whose header is fine but whose data is corrupt is found when its turn
            comes); or nobody found in any image.
    """
    files = check_image_folders(folders)
    names = view_names(folders)
    T = len(files[0])
    kp, sc, skeleton = _detect_views(
        names,
        folders,
        input_fingerprint(folders, "images"),
        T,
        lambda v: image_frames(files[v]),
        detector,
        batch,
        cache_dir,
        progress,
        workers,
    )
    return Keypoints2D(kp, sc, skeleton, names, np.arange(T), fps)
