"""2D keypoint detectors run on MHP renders, so the training 2D noise is a real detector's.

A detector is anything that follows :class:`Detector`: images in, COCO-17 pixel keypoints
and confidences out, for one person per image or, with a people axis, several
(:class:`MultiPersonDetector`; :func:`with_people_axis` gives both the same shape).
Missing keypoints are NaN with score 0, and keypoints outside the image get score 0 (as in
the thesis's generator). Pixels follow rmpl's convention: from the
top-left, pixel ``(i, j)`` centred on ``(i, j)``.

:class:`MediaPipeDetector` wraps MediaPipe's BlazePose (``mediapipe==0.10.14``, the legacy
``mp.solutions.pose`` API, ``model_complexity=1``, whose weights ship in the wheel; the other
complexities and newer mediapipe download weights at run time). Its 33 landmarks are mapped
to COCO-17 by name, with the landmark *visibility* as the score.

The multi-person detector of the video path, BlazePose's networks run for every person, is
:class:`rmpl.synth.detect_multi.BlazePoseMulti`.

Shape glossary: ``B`` images, ``N`` people in an image, ``J`` joints (17).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from rmpl.skeleton import BLAZEPOSE33, EMBED_ALIASES, Skeleton, skeleton_for

__all__ = [
    "Detector",
    "MultiPersonDetector",
    "MediaPipeDetector",
    "DETECTORS",
    "max_people",
    "with_people_axis",
    "zero_outside",
    "as_image_list",
    "blazepose_indices",
]

Images = np.ndarray | Sequence[np.ndarray]


@runtime_checkable
class Detector(Protocol):
    """A 2D keypoint detector.

    ``__call__(images)`` takes RGB uint8 images, shape (B, H, W, 3) or a sequence of
    (H_i, W_i, 3) arrays of any sizes, and returns ``(keypoints, scores)`` in ``skeleton``'s
    joint order: pixels and confidences in [0, 1]. A single-person detector returns shapes
    (B, J, 2) and (B, J); a detector with an integer attribute ``max_people``
    (:class:`MultiPersonDetector`) returns (B, N, J, 2) and (B, N, J) with
    N <= ``max_people``, an empty slot being NaN with score 0. Missing joints are NaN with
    score 0; joints outside the image have score 0.
    """

    name: str
    skeleton: Skeleton

    def __call__(self, images: Images) -> tuple[np.ndarray, np.ndarray]: ...


@runtime_checkable
class MultiPersonDetector(Detector, Protocol):
    """A :class:`Detector` with a people axis: (B, N, J, 2) keypoints, (B, N, J) scores.

    It may follow people from image to image (the images of a call, and of the calls that
    follow, are then consecutive frames of one video, and a person keeps its slot ``n``);
    :meth:`reset` starts a new video. Callers reset before each video.
    """

    max_people: int

    def reset(self) -> None: ...


def max_people(detector: Detector) -> int:
    """People per image the detector can return: its ``max_people``, else 1."""
    return int(getattr(detector, "max_people", 1))


def with_people_axis(
    detector: Detector, keypoints: np.ndarray, scores: np.ndarray, num_images: int
) -> tuple[np.ndarray, np.ndarray]:
    """A detector's output as (B, N, J, 2) keypoints and (B, N, J) scores, checked.

    A single-person detector's (B, J, 2) and (B, J) get N = 1.

    Raises:
        ValueError: shapes that are not the detector's protocol (a programming error in the
            detector, named in the message).
    """
    keypoints, scores = np.asarray(keypoints, float), np.asarray(scores, float)
    J, N = detector.skeleton.num_joints, max_people(detector)
    if N == 1 and keypoints.ndim == 3:
        keypoints, scores = keypoints[:, None], scores[:, None]
    ok = (
        keypoints.ndim == 4
        and keypoints.shape[0] == num_images
        and keypoints.shape[1] <= N
        and keypoints.shape[2:] == (J, 2)
        and scores.shape == keypoints.shape[:3]
    )
    if not ok:
        want = f"({num_images}, N <= {N}, {J}, 2) and ({num_images}, N, {J})"
        raise ValueError(
            f"detector {getattr(detector, 'name', detector)!r} returned keypoints "
            f"{keypoints.shape} and scores {scores.shape}; expected {want}"
        )
    return keypoints, scores


def as_image_list(images: Images) -> list[np.ndarray]:
    """Validate images: a (B, H, W, 3) uint8 array or a sequence of (H, W, 3) uint8 arrays."""
    if isinstance(images, np.ndarray):
        if images.ndim != 4 or images.shape[-1] != 3:
            raise ValueError(f"images must have shape (B, H, W, 3), got {images.shape}")
        images = list(images)
    out = []
    for i, im in enumerate(images):
        im = np.asarray(im)
        if im.ndim != 3 or im.shape[-1] != 3 or im.dtype != np.uint8:
            raise ValueError(
                f"image {i} must be RGB uint8 of shape (H, W, 3), got {im.dtype} {im.shape}"
            )
        out.append(im)
    return out


def zero_outside(keypoints: np.ndarray, scores: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Scores with joints outside their image set to 0.

    Args:
        keypoints: pixels, shape (*, J, 2). scores: shape (*, J).
        size: image (width, height) in pixels, shape (*, 2).

    Returns:
        Scores, shape (*, J); NaN keypoints also get 0.

    >>> kp = np.array([[[5.0, 5.0], [-1.0, 5.0], [np.nan, np.nan]]])
    >>> zero_outside(kp, np.ones((1, 3)), np.array([[10, 10]])).tolist()
    [[1.0, 0.0, 0.0]]
    """
    size = np.asarray(size, dtype=float)[..., None, :]  # (*, 1, 2)
    with np.errstate(invalid="ignore"):
        # Pixel i covers [i - 0.5, i + 0.5).
        inside = np.all((keypoints >= -0.5) & (keypoints < size - 0.5), axis=-1)
    return np.where(inside, scores, 0.0)


def blazepose_indices(skeleton: Skeleton) -> np.ndarray:
    """For each joint of ``skeleton``, the BlazePose landmark that gives it, (J,) int; -1
    where BlazePose has none (HALPE-26's head top, neck, mid-hip and small toes). The foot
    index stands in for the big toe (:data:`rmpl.skeleton.EMBED_ALIASES`)."""
    alias = EMBED_ALIASES["blazepose33"]
    names = [alias.get(n, n) for n in skeleton.joints]
    return np.array([BLAZEPOSE33._index.get(n, -1) for n in names])


def pick_landmarks(landmarks: np.ndarray, source: np.ndarray) -> np.ndarray:
    """Rows ``source`` (J,) of ``landmarks`` (33, C), NaN where ``source`` is -1: (J, C)."""
    out = np.asarray(landmarks, float)[np.maximum(source, 0)]
    out[source < 0] = np.nan
    return out


class MediaPipeDetector:
    """MediaPipe BlazePose (33 landmarks) mapped to HALPE-26 or COCO-17, one person per
    image.

    Args:
        model_complexity: BlazePose model; only 1 ships in the ``mediapipe==0.10.14`` wheel.
        min_detection_confidence: person-detector threshold; below it the image is a miss.
        joints: ``"halpe26"`` (COCO-17 + heels + foot index as the big toe; the head top,
            neck, mid-hip and small toes missing) or ``"coco17"``.

    Use it as a context manager, or call :meth:`close`, to free the MediaPipe graph.
    """

    name = "mediapipe"

    def __init__(
        self,
        model_complexity: int = 1,
        min_detection_confidence: float = 0.5,
        joints: str = "halpe26",
    ) -> None:
        self.skeleton = skeleton_for(joints)
        self._source = blazepose_indices(self.skeleton)
        try:
            import mediapipe as mp
        except ImportError as e:
            raise ImportError(
                "MediaPipeDetector needs mediapipe==0.10.14: pip install 'rmpl[synth]'"
            ) from e
        # Each image is a new scene: static mode runs the person detector every time
        # instead of tracking from the previous image.
        self._pose = mp.solutions.pose.Pose(
            static_image_mode=True,
            model_complexity=model_complexity,
            enable_segmentation=False,
            min_detection_confidence=min_detection_confidence,
        )

    def close(self) -> None:
        self._pose.close()

    def __enter__(self) -> MediaPipeDetector:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __call__(self, images: Images) -> tuple[np.ndarray, np.ndarray]:
        """Detect. See :class:`Detector`. Returns keypoints (B, J, 2), scores (B, J)."""
        images = as_image_list(images)
        J = self.skeleton.num_joints
        keypoints = np.full((len(images), J, 2), np.nan)
        scores = np.zeros((len(images), J))
        sizes = np.zeros((len(images), 2))
        for i, im in enumerate(images):
            h, w = im.shape[:2]
            sizes[i] = w, h
            result = self._pose.process(np.ascontiguousarray(im))
            if result.pose_landmarks is None:
                continue
            lm = result.pose_landmarks.landmark
            xyv = pick_landmarks([(p.x, p.y, p.visibility) for p in lm], self._source)
            # Normalised coordinates run from the image's left/top edge (0) to its right/bottom
            # edge (1); rmpl's pixel centres are at integers.
            keypoints[i] = xyv[:, :2] * (w, h) - 0.5
            scores[i] = np.clip(np.nan_to_num(xyv[:, 2]), 0.0, 1.0)
        return keypoints, zero_outside(keypoints, scores, sizes)


#: Detector factories by name.
DETECTORS: dict[str, Callable[..., Detector]] = {"mediapipe": MediaPipeDetector}
