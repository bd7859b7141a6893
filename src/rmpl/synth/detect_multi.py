"""Several people per image with BlazePose's own two networks, offline, from the mediapipe wheel.

MediaPipe's legacy ``Pose`` solution finds one person per image. Its two networks ship in the
``mediapipe==0.10.14`` wheel (Apache-2.0) and are run here directly, so nothing is downloaded:

1. the person detector ``modules/pose_detection/pose_detection.tflite`` (224 x 224, an SSD
   over 2,254 anchors; each detection is a box plus 4 keypoints: mid-hip, a point whose
   distance from the mid-hip is the body's radius, mid-shoulder and an upper-body point),
   decoded and suppressed here (:func:`ssd_anchors`, :func:`decode_detections`,
   :func:`weighted_nms`) for every person instead of the best one;
2. the landmark network ``modules/pose_landmark/pose_landmark_full.tflite`` (256 x 256) on a
   rotated square crop around each person (:func:`roi_from_points`, :func:`crop_affine`):
   33 landmarks with visibilities, a person-presence score, and 2 auxiliary landmarks from
   which the next frame's crop is made.

Like BlazePose's own tracking mode, a person found in one frame is followed into the next
through the crop its auxiliary landmarks give, so the detector is only needed to find new
people. The detector's input is square, so in a long image (a portrait 1080 x 1920 video)
people are small in a whole-image view and it misses some: it also looks at square
windows of the image (:func:`detector_windows`; ``window_scales`` adds smaller ones, for
people far from the camera). On a frame where nobody is followed it
looks at the whole image and every window; where someone was lost, at the whole image;
otherwise at one of them every ``detect_every`` frames, in turn. A followed person keeps its
slot in the people axis while the landmark network says it is present. Two crops that
converge on one person keep one result (the earlier slot's), and a result most of whose
landmarks lie on a bigger person's bones (the landmark network drawing a small person on
someone's legs) is dropped. Known limit: where one person stands close in front of another,
the landmark network can mix the two (a leg of one on the other's body); the 3D stages see
such a view as disagreeing.

The networks run on MediaPipe's own TFLite runtime (XNNPACK) through the Tasks
``ImageEmbedder``, which returns a network's raw output tensors. It needs input
normalisation metadata, which the wheel's files lack: :func:`model_buffer` adds it (with
mediapipe's metadata writer) and drops the landmark network's segmentation and heat-map
outputs, in memory. The same bundle also makes MediaPipe's ``PoseLandmarker`` Task run
(:func:`pose_landmarker_bundle`), which ``rmpl.benchmarks.bench_detect`` compares against.

Pixels follow rmpl's convention (from the top-left, pixel ``(i, j)`` centred on ``(i, j)``);
inside this module coordinates are continuous (the image's left edge is x = 0), as
MediaPipe's, and shifted by -0.5 on output.

Shape glossary: ``B`` images, ``N`` people in an image (slots), ``J`` joints (17), ``A``
anchors (2,254), ``n`` detections.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.skeleton import skeleton_for
from rmpl.synth.detect import (
    Images,
    as_image_list,
    blazepose_indices,
    pick_landmarks,
    zero_outside,
)

__all__ = [
    "BlazePoseMulti",
    "ssd_anchors",
    "decode_detections",
    "weighted_nms",
    "roi_from_points",
    "crop_affine",
    "detector_windows",
    "segment_distance",
    "model_buffer",
    "pose_landmarker_bundle",
]

log = logging.getLogger(__name__)

DETECTOR_SIZE = 224  #: the person detector's input, pixels
LANDMARK_SIZE = 256  #: the landmark network's input, pixels
_DETECTOR_FILE = "modules/pose_detection/pose_detection.tflite"
_LANDMARK_FILE = "modules/pose_landmark/pose_landmark_full.tflite"
#: How far a person's crop extends past the detected body circle (MediaPipe's 1.25).
ROI_ENLARGE = 1.25


# --------------------------------------------------------------------------- math


def ssd_anchors(
    size: int = DETECTOR_SIZE, strides: tuple[int, ...] = (8, 16, 32, 32, 32)
) -> np.ndarray:
    """Anchor centres of BlazePose's person detector, normalised to [0, 1], shape (A, 2).

    Two anchors per cell and layer (aspect 1 and its interpolated scale), layers of the same
    stride sharing one grid; all anchors have size 1 (the network regresses absolute sizes).

    >>> ssd_anchors().shape
    (2254, 2)
    """
    out, layer = [], 0
    while layer < len(strides):
        same = [s for s in strides[layer:] if s == strides[layer]]
        cells = int(np.ceil(size / strides[layer]))
        c = (np.arange(cells) + 0.5) / cells
        grid = np.stack(np.meshgrid(c, c), -1).reshape(-1, 1, 2)  # (cells^2, 1, 2): x, y
        out.append(np.repeat(grid, 2 * len(same), axis=1).reshape(-1, 2))
        layer += len(same)
    return np.concatenate(out)


def decode_detections(
    raw: np.ndarray, logits: np.ndarray, anchors: np.ndarray, min_score: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The detector's raw output as boxes and keypoints, normalised to its input.

    Args:
        raw: regressions, shape (A, 12): box centre x, y, width, height, then 4 keypoints
            (x, y), in input pixels relative to the anchor centre.
        logits: scores before the sigmoid, shape (A,).
        anchors: :func:`ssd_anchors`, shape (A, 2).
        min_score: keep detections scoring at least this, in (0, 1).

    Returns:
        boxes (n, 4) as centre x, y, width, height; keypoints (n, 4, 2); scores (n,).
    """
    scores = 1.0 / (1.0 + np.exp(-np.clip(logits, -100.0, 100.0)))
    keep = scores >= min_score
    r, a = raw[keep] / DETECTOR_SIZE, anchors[keep]
    boxes = np.concatenate([r[:, :2] + a, r[:, 2:4]], axis=1)
    keypoints = r[:, 4:12].reshape(-1, 4, 2) + a[:, None]
    return boxes, keypoints, scores[keep]


def box_iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Intersection over union of one centre-size box (4,) with others (n, 4): (n,).

    >>> box_iou(np.array([0.0, 0, 2, 2]), np.array([[1.0, 0, 2, 2], [5, 5, 1, 1]])).round(3)
    array([0.333, 0.   ])
    """
    lo = np.maximum(box[:2] - box[2:] / 2, boxes[:, :2] - boxes[:, 2:] / 2)
    hi = np.minimum(box[:2] + box[2:] / 2, boxes[:, :2] + boxes[:, 2:] / 2)
    inter = np.prod(np.clip(hi - lo, 0.0, None), axis=1)
    union = np.prod(box[2:]) + np.prod(boxes[:, 2:], axis=1) - inter
    return inter / np.maximum(union, 1e-12)


def weighted_nms(
    boxes: np.ndarray, keypoints: np.ndarray, scores: np.ndarray, iou_threshold: float = 0.3
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted non-maximum suppression (MediaPipe's, for BlazePose's detector).

    The best remaining detection and every other one overlapping it by more than
    ``iou_threshold`` become one detection: their score-weighted mean box and keypoints,
    with the best score.

    Args:
        boxes: (n, 4) centre-size; keypoints: (n, K, 2); scores: (n,).

    Returns:
        The merged boxes (m, 4), keypoints (m, K, 2), scores (m,), best first.
    """
    order = np.argsort(-scores)
    boxes, keypoints, scores = boxes[order], keypoints[order], scores[order]
    alive = np.ones(len(scores), bool)
    out_b, out_k, out_s = [], [], []
    for i in range(len(scores)):
        if not alive[i]:
            continue
        group = alive & (box_iou(boxes[i], boxes) > iou_threshold)
        group[i] = True
        w = scores[group] / scores[group].sum()
        out_b.append(w @ boxes[group])
        out_k.append(np.einsum("n,nkc->kc", w, keypoints[group]))
        out_s.append(scores[i])
        alive &= ~group
    K = keypoints.shape[1] if keypoints.ndim == 3 else 0
    if not out_s:
        return np.zeros((0, 4)), np.zeros((0, K, 2)), np.zeros(0)
    return np.array(out_b), np.array(out_k), np.array(out_s)


def roi_from_points(
    centre: np.ndarray, scale_point: np.ndarray, enlarge: float = ROI_ENLARGE
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A person's square crop from two points (MediaPipe's alignment rule).

    The crop is centred on ``centre`` (the mid-hip), its side is ``2 * enlarge`` times the
    distance to ``scale_point``, and it is rotated so that the direction from ``centre`` to
    ``scale_point`` points up in the crop.

    Args:
        centre, scale_point: pixels, shape (*, 2).

    Returns:
        centre (*, 2) pixels, side (*,) pixels, angle (*,) radians in [-pi, pi).

    >>> c, s, a = roi_from_points(np.array([10.0, 20.0]), np.array([10.0, 0.0]))
    >>> c.tolist(), float(s), float(a)
    ([10.0, 20.0], 50.0, 0.0)
    """
    d = scale_point - centre
    side = 2.0 * enlarge * np.linalg.norm(d, axis=-1)
    angle = np.pi / 2 - np.arctan2(-d[..., 1], d[..., 0])
    angle = (angle + np.pi) % (2 * np.pi) - np.pi
    return np.asarray(centre, float), side, angle


def crop_affine(centre: np.ndarray, side: float, angle: float, size: int) -> np.ndarray:
    """The affine map from a crop's pixels to the image's, shape (2, 3).

    A point ``q`` of the (size x size) crop is at ``M[:, :2] @ q + M[:, 2]`` in the image;
    both in continuous coordinates (left/top edge 0).

    >>> M = crop_affine(np.array([50.0, 60.0]), 20.0, 0.0, 10)
    >>> (M[:, :2] @ [5.0, 5.0] + M[:, 2]).tolist()
    [50.0, 60.0]
    """
    c, s = np.cos(angle), np.sin(angle)
    A = side / size * np.array([[c, -s], [s, c]])
    return np.concatenate([A, (np.asarray(centre) - A @ [size / 2, size / 2])[:, None]], axis=1)


def detector_windows(
    height: int, width: int, scales: tuple[float, ...] = (1.0,)
) -> list[tuple[int, int, int, int]]:
    """Where the person detector looks: the whole image, then, for each scale, squares of
    that fraction of the short side tiling the image and overlapping their neighbours by
    about half (the detector's input is square and 224 pixels, so a person in a long image,
    or far from the camera, is small in the whole-image view). A scale whose squares would
    only repeat the whole image (within 10% on both sides) adds none.

    Args:
        height, width: the image, pixels.
        scales: window sides as fractions of the short side, each in (0, 1]; 1 gives
            squares of the short side along the long side.

    Returns:
        windows (x0, y0, x1, y1), pixels; the first is the whole image.

    >>> detector_windows(1920, 1080)
    [(0, 0, 1080, 1920), (0, 0, 1080, 1080), (0, 420, 1080, 1500), (0, 840, 1080, 1920)]
    >>> detector_windows(100, 100)
    [(0, 0, 100, 100)]
    >>> w = detector_windows(100, 100, (1.0, 0.5))  # a 3 x 3 grid of half-side squares
    >>> len(w), w[1:4], w[-1]
    (10, [(0, 0, 50, 50), (25, 0, 75, 50), (50, 0, 100, 50)], (50, 50, 100, 100))
    """
    out = [(0, 0, width, height)]
    for scale in scales:
        side = max(1, round(scale * min(height, width)))
        xs, ys = _window_starts(width, side), _window_starts(height, side)
        if len(xs) == len(ys) == 1:
            continue  # the whole image again
        out += [(x, y, x + side, y + side) for y in ys for x in xs]
    return out


def _window_starts(length: int, side: int) -> list[int]:
    """Starts of windows of ``side`` pixels covering ``length``, overlapping by about half;
    one, centred, when ``length`` exceeds ``side`` by less than 10%."""
    if length - side < 0.1 * side:
        return [(length - side) // 2]
    count = int(np.ceil(2 * length / side - 1))
    return [int(s) for s in np.linspace(0, length - side, count).round().astype(int)]


def _apply(M: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (*, 2) through an affine map (2, 3)."""
    return points @ M[:, :2].T + M[:, 2]


def _is_fraction(value) -> bool:
    """Whether ``value`` is a number (not a bool) in (0, 1]."""
    return isinstance(value, int | float) and not isinstance(value, bool) and 0 < value <= 1


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x, -100.0, 100.0)))


# --------------------------------------------------------------------------- networks


def _wheel_file(name: str) -> Path:
    try:
        import mediapipe
    except ImportError as e:
        raise ImportError(
            "BlazePoseMulti needs mediapipe==0.10.14 (its networks ship in the wheel): "
            "pip install 'rmpl[detect]'"
        ) from e
    path = Path(mediapipe.__file__).parent / name
    if not path.is_file():
        raise ImportError(
            f"{path} is missing: BlazePoseMulti needs the networks shipped in the "
            f"mediapipe==0.10.14 wheel (found mediapipe {mediapipe.__version__})"
        )
    return path


def model_buffer(which: str, keep_outputs: tuple[int, ...] | None = None) -> bytes:
    """A wheel network with the input metadata MediaPipe's Tasks need, in memory.

    Args:
        which: ``"detector"`` (input scaled to [-1, 1]) or ``"landmarks"`` ([0, 1]).
        keep_outputs: indices of the output tensors to keep (all when None). The landmark
            network's outputs are 0 landmarks (195), 1 presence, 2 segmentation,
            3 heat maps, 4 world landmarks; copying 2 and 3 would double its cost.

    Returns:
        The TFLite flatbuffer with image-input normalisation metadata.
    """
    import flatbuffers
    from mediapipe.tasks.metadata import schema_py_generated as schema
    from mediapipe.tasks.python.metadata.metadata_writers import metadata_writer as mw

    path, mean, std = {
        "detector": (_DETECTOR_FILE, 127.5, 127.5),
        "landmarks": (_LANDMARK_FILE, 0.0, 255.0),
    }[which]
    data = _wheel_file(path).read_bytes()
    outputs = None
    if keep_outputs is not None:
        model = schema.ModelT.InitFromObj(schema.Model.GetRootAsModel(data, 0))
        graph = model.subgraphs[0]
        graph.outputs = np.asarray([graph.outputs[i] for i in keep_outputs], np.int32)
        builder = flatbuffers.Builder(len(data) + 4096)
        builder.Finish(model.Pack(builder), file_identifier=b"TFL3")
        data, outputs = bytes(builder.Output()), len(keep_outputs)
    writer = mw.MetadataWriter.create(bytearray(data))
    writer.add_general_info(Path(path).stem, "from the mediapipe 0.10.14 wheel, for rmpl")
    writer.add_image_input(
        norm_mean=[mean], norm_std=[std], color_space_type=mw.metadata_fb.ColorSpaceType.RGB
    )
    count = outputs if outputs is not None else {"detector": 2, "landmarks": 5}[which]
    for i in range(count):
        writer.add_feature_output(name=f"output_{i}")
    out, _ = writer.populate()
    return bytes(out)


def pose_landmarker_bundle(path: str | Path) -> Path:
    """Write a MediaPipe ``PoseLandmarker`` Task bundle (.task, a zip) from the wheel's two
    networks, for comparison; ``PoseLandmarkerOptions(num_poses=...)`` accepts it."""
    import zipfile

    from rmpl.io.atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp, zipfile.ZipFile(tmp, "w") as z:
        z.writestr("pose_detector.tflite", model_buffer("detector"))
        z.writestr("pose_landmarks_detector.tflite", model_buffer("landmarks"))
    return path


class _Network:
    """One TFLite network on MediaPipe's runtime: an RGB uint8 square image of the network's
    size in, its raw output tensors out (flat float arrays)."""

    def __init__(self, buffer: bytes) -> None:
        from mediapipe.tasks.python import BaseOptions, vision

        options = vision.ImageEmbedderOptions(
            base_options=BaseOptions(model_asset_buffer=buffer), l2_normalize=False, quantize=False
        )
        self._embedder = vision.ImageEmbedder.create_from_options(options)

    def __call__(self, image: np.ndarray) -> list[np.ndarray]:
        import mediapipe as mp

        image = mp.Image(image_format=mp.ImageFormat.SRGB, data=np.ascontiguousarray(image))
        with warnings.catch_warnings():  # protobuf's deprecation notice, once per process
            warnings.filterwarnings("ignore", "SymbolDatabase.GetPrototype", UserWarning)
            result = self._embedder.embed(image)
        return [np.asarray(e.embedding, np.float64) for e in result.embeddings]

    def close(self) -> None:
        self._embedder.close()


# --------------------------------------------------------------------------- detector


@dataclass
class _Person:
    """One followed person: its crop for the next frame and its last landmarks."""

    centre: np.ndarray  # (2,) continuous pixels
    side: float
    angle: float
    landmarks: np.ndarray  # (33, 2) continuous pixels
    visibility: np.ndarray  # (33,)
    presence: float


class BlazePoseMulti:
    """BlazePose for several people per image, following people from frame to frame.

    Follows :class:`rmpl.synth.detect.Detector` with a people axis: ``__call__`` returns
    keypoints (B, N, J, 2) and scores (B, N, J) in ``skeleton``'s joint set (HALPE-26 or
    COCO-17, see ``joints``) with ``N = max_people`` slots;
    an empty slot is NaN with score 0. With ``track=True`` the images of one call, and of
    the calls that follow, are taken as consecutive frames of one video, and a person keeps
    its slot while followed: call :meth:`reset` before another video (``detect2d`` does).

    Args:
        max_people: slots per image, at least 1.
        min_detection: person-detector score to start following someone, in (0, 1).
        min_presence: landmark network's presence score to keep a person, in (0, 1).
        track: follow people into the next frame; False treats every image afresh.
        detect_every: with ``track``, run the person detector on one window every k-th
            frame (on all of them where nobody is followed, on the whole image where someone
            was lost); 1 runs it on every frame.
        same_person: two results whose landmarks (visible in both) lie within this fraction
            of the body size, in median, are one person, and so is a result most of whose
            landmarks lie this close to another's bones (a phantom); the earlier slot
            keeps it.
        nms_iou: the person detector's boxes overlapping the best one by more than this
            intersection over union are merged into it (:func:`weighted_nms`), in (0, 1];
            0.3 is MediaPipe's single-person setting.
        window_scales: the detector's square windows beyond the whole image, as fractions
            of the image's short side, each in (0, 1] (:func:`detector_windows`); smaller
            windows find people far from the camera but cost a detector run each (a 0.5
            scale adds 21 windows to a 1920 x 1080 image, 9 to a square one). With
            ``track``, the windows beyond the whole image are scanned all at once only
            where nobody is followed, otherwise one per ``detect_every`` frames in turn.
        joints: ``"halpe26"`` (COCO-17 + heels + foot index as the big toe; the head top,
            neck, mid-hip and small toes missing) or ``"coco17"``.

    Use it as a context manager, or call :meth:`close`, to free the networks.
    """

    name = "blazepose-multi"

    def __init__(
        self,
        max_people: int = 4,
        min_detection: float = 0.5,
        min_presence: float = 0.5,
        track: bool = True,
        detect_every: int = 1,
        same_person: float = 0.1,
        joints: str = "halpe26",
        nms_iou: float = 0.3,
        window_scales: tuple[float, ...] = (1.0,),
    ) -> None:
        if max_people < 1 or detect_every < 1:
            raise ValueError(f"max_people and detect_every must be >= 1, got {max_people}, "
                             f"{detect_every}")  # fmt: skip
        for label, value in (("min_detection", min_detection), ("min_presence", min_presence)):
            if not 0 < value < 1:
                raise ValueError(f"{label} must be in (0, 1), got {value}")
        if not _is_fraction(nms_iou):
            raise ValueError(f"nms_iou must be a number in (0, 1], got {nms_iou!r}")
        scales = window_scales if isinstance(window_scales, list | tuple) else [window_scales]
        if not all(_is_fraction(v) for v in scales):
            raise ValueError(
                "window_scales must be a list of fractions of the image's short side, each "
                f"in (0, 1], got {window_scales!r}"
            )
        self.max_people = int(max_people)
        self.min_detection, self.min_presence = min_detection, min_presence
        self.nms_iou, self.window_scales = float(nms_iou), tuple(float(v) for v in scales)
        self.track, self.detect_every, self.same_person = track, int(detect_every), same_person
        if not track:
            self.name = "blazepose-multi-static"
        self._detector = _Network(model_buffer("detector"))
        self._landmarks = _Network(model_buffer("landmarks", keep_outputs=(0, 1)))
        self._anchors = ssd_anchors()
        self.skeleton = skeleton_for(joints)
        self._source = blazepose_indices(self.skeleton)  # (J,), -1 = BlazePose has none
        self.calls = {"detector": 0, "landmarks": 0}  # network runs, for benchmarks
        self.reset()

    def reset(self) -> None:
        """Forget the people followed so far (the next image starts a new video)."""
        self._slots: list[_Person | None] = [None] * self.max_people
        self._frame = 0

    def close(self) -> None:
        self._detector.close()
        self._landmarks.close()

    def __enter__(self) -> BlazePoseMulti:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __call__(self, images: Images) -> tuple[np.ndarray, np.ndarray]:
        """Detect. Returns keypoints (B, N, J, 2) px and scores (B, N, J), J of ``skeleton``."""
        images = as_image_list(images)
        B, N, J = len(images), self.max_people, self.skeleton.num_joints
        keypoints = np.full((B, N, J, 2), np.nan)
        scores = np.zeros((B, N, J))
        sizes = np.zeros((B, N, 2))
        for b, image in enumerate(images):
            if not self.track:
                self.reset()
            self._step(image)
            sizes[b] = image.shape[1], image.shape[0]
            for n, person in enumerate(self._slots):
                if person is not None:
                    # pixel centres
                    keypoints[b, n] = pick_landmarks(person.landmarks, self._source) - 0.5
                    seen = pick_landmarks(person.visibility[:, None], self._source)[:, 0]
                    scores[b, n] = np.nan_to_num(seen)
        return keypoints, zero_outside(keypoints, scores, sizes)

    # ------------------------------------------------------------------ one frame

    def _step(self, image: np.ndarray) -> None:
        """Update the slots from one RGB frame (H, W, 3)."""
        found: list[tuple[int | None, _Person]] = []

        def add(slot: int | None, person: _Person | None) -> None:
            # Two crops that converged on one person: the earlier slot keeps it. A phantom
            # on another person's body goes, whichever came first.
            if person is None or any(
                self._same(person, q) or self._phantom(person, q) for _, q in found
            ):
                return
            found[:] = [(n, q) for n, q in found if not self._phantom(q, person)]
            found.append((slot, person))

        followed = [(n, p) for n, p in enumerate(self._slots) if p is not None]
        for n, p in followed:
            add(n, self._landmark(image, p.centre, p.side, p.angle))
        windows = detector_windows(*image.shape[:2], self.window_scales)
        if not self.track or not found:
            scan = windows  # every image afresh, or nobody followed: look everywhere now
        elif len(found) < len(followed):
            scan = windows[:1]  # someone lost: the whole image now, the windows in turn
        elif self._frame % self.detect_every == 0:
            # One detector run per frame, cycling through the whole image and its windows.
            scan = [windows[(self._frame // self.detect_every) % len(windows)]]
        else:
            scan = []
        detections: list[tuple] = []
        for window in scan:
            for d in self._detect(image, window):
                if not any(self._near(d[3], d[4], q[3], q[4], d[1]) for q in detections):
                    detections.append(d)
        for centre, side, angle, hip, shoulder in detections:
            if len(found) == self.max_people:
                break
            if not any(self._is_followed(hip, shoulder, q) for _, q in found):
                add(None, self._landmark(image, centre, side, angle))
        self._frame += 1
        self._assign_slots(found)

    def _assign_slots(self, found: list[tuple[int | None, _Person]]) -> None:
        """People followed keep their slot; new ones take the first free slots."""
        slots: list[_Person | None] = [None] * self.max_people
        for slot, person in found:
            if slot is not None:
                slots[slot] = person
        for slot, person in found:
            if slot is None and None in slots:
                slots[slots.index(None)] = person
        self._slots = slots

    def _detect(self, image: np.ndarray, window: tuple[int, int, int, int]) -> list[tuple]:
        """People in one window (x0, y0, x1, y1) of an image, best first: (crop centre,
        side, angle, mid-hip, mid-shoulder) in image pixels."""
        import cv2

        x0, y0, x1, y1 = window
        w, h = x1 - x0, y1 - y0
        scale = DETECTOR_SIZE / max(h, w)
        nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
        # Bilinear, as MediaPipe's own CPU preprocessing (area averaging costs 10x more).
        small = cv2.resize(image[y0:y1, x0:x1], (nw, nh), interpolation=cv2.INTER_LINEAR)
        px, py = (DETECTOR_SIZE - nw) // 2, (DETECTOR_SIZE - nh) // 2
        square = np.zeros((DETECTOR_SIZE, DETECTOR_SIZE, 3), np.uint8)
        square[py : py + nh, px : px + nw] = small  # letterboxed, as MediaPipe does
        raw, logits = self._detector(square)
        self.calls["detector"] += 1
        boxes, kps, scores = decode_detections(
            raw.reshape(-1, 12), logits, self._anchors, self.min_detection
        )
        boxes, kps, scores = weighted_nms(boxes, kps, scores, self.nms_iou)
        kps = (kps * DETECTOR_SIZE - [px, py]) * [w / nw, h / nh] + [x0, y0]  # (n, 4, 2)
        out = []
        for k in kps:
            centre, side, angle = roi_from_points(k[0], k[1])
            out.append((centre, float(side), float(angle), k[0], k[2]))
        return out

    def _landmark(self, image: np.ndarray, centre, side: float, angle: float) -> _Person | None:
        """Landmarks in one crop, or None when the network says nobody is there."""
        import cv2

        if not side > 1.0:
            return None
        M = crop_affine(centre, side, angle, LANDMARK_SIZE)
        # warpAffine maps destination pixel indices to source pixel indices (centres at
        # integers): shift the continuous-coordinate map by half a pixel on both sides.
        Mi = M.copy()
        Mi[:, 2] = _apply(M, np.full(2, 0.5)) - 0.5
        crop = cv2.warpAffine(
            image,
            Mi,
            (LANDMARK_SIZE, LANDMARK_SIZE),
            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
            borderMode=cv2.BORDER_CONSTANT,
        )
        raw, presence = self._landmarks(crop)
        self.calls["landmarks"] += 1
        presence = float(presence[0])
        if presence < self.min_presence:
            return None
        raw = raw.reshape(39, 5)  # 33 landmarks + 2 auxiliary + 4 unused; x, y, z, vis, pres
        points = _apply(M, raw[:35, :2])
        nxt_centre, nxt_side, nxt_angle = roi_from_points(points[33], points[34])
        return _Person(
            nxt_centre, float(nxt_side), float(nxt_angle), points[:33], _sigmoid(raw[:33, 3]),
            presence,
        )  # fmt: skip

    def _size(self, person: _Person) -> float:
        return person.side / ROI_ENLARGE

    def _near(self, hip, shoulder, hip2, shoulder2, side: float) -> bool:
        """Whether two mid-hip/mid-shoulder pairs are one person of crop side ``side``."""
        d = max(np.linalg.norm(hip - hip2), np.linalg.norm(shoulder - shoulder2))
        return d < 2 * self.same_person * side / ROI_ENLARGE

    def _is_followed(self, hip: np.ndarray, shoulder: np.ndarray, person: _Person) -> bool:
        """Whether a detection (its mid-hip and mid-shoulder) is a person already followed."""
        lm = person.landmarks
        return self._near(hip, shoulder, (lm[23] + lm[24]) / 2, (lm[11] + lm[12]) / 2,
                          person.side)  # fmt: skip

    def _same(self, a: _Person, b: _Person) -> bool:
        """Whether result ``a`` is person ``b`` again: the landmarks visible in both agree
        (median distance below ``same_person`` times the body size)."""
        both = (a.visibility > 0.5) & (b.visibility > 0.5)
        if both.sum() < 4:
            both = np.ones_like(both)
        d = np.median(np.linalg.norm(a.landmarks[both] - b.landmarks[both], axis=-1))
        return bool(d < self.same_person * max(self._size(a), self._size(b)))

    def _phantom(self, a: _Person, b: _Person) -> bool:
        """Whether result ``a`` is a phantom on person ``b``'s body: most of its visible
        landmarks lie on ``b``'s bones (within ``same_person`` times ``b``'s size), as when
        the landmark network, given a crop of someone's legs, draws a small person there."""
        seen = a.visibility > 0.5
        bones = [(i, j) for i, j in _BONES if b.visibility[i] > 0.5 and b.visibility[j] > 0.5]
        if seen.sum() < 4 or not bones or self._size(a) > self._size(b):
            return False
        near = segment_distance(a.landmarks[seen], b.landmarks, bones)
        return bool(np.mean(near < self.same_person * self._size(b)) > PHANTOM_SHARE)


#: BlazePose's body bones (landmark indices): head to shoulders, arms, torso, legs, feet.
_BONES = (
    (0, 11), (0, 12), (11, 12), (11, 13), (13, 15), (12, 14), (14, 16), (11, 23), (12, 24),
    (23, 24), (23, 25), (25, 27), (27, 31), (24, 26), (26, 28), (28, 32),
)  # fmt: skip
#: Share of a result's visible landmarks on another person's bones that makes it a phantom.
PHANTOM_SHARE = 0.8


def segment_distance(points: np.ndarray, landmarks: np.ndarray, bones) -> np.ndarray:
    """Distance of each point to the nearest bone (segment between two landmarks).

    Args:
        points: pixels, shape (n, 2). landmarks: pixels, shape (L, 2).
        bones: pairs of landmark indices, at least one.

    Returns:
        Distances in pixels, shape (n,).

    >>> lm = np.array([[0.0, 0.0], [10.0, 0.0]])
    >>> segment_distance(np.array([[5.0, 3.0], [13.0, 4.0]]), lm, [(0, 1)]).tolist()
    [3.0, 5.0]
    """
    a = landmarks[[i for i, _ in bones]]  # (S, 2)
    ab = landmarks[[j for _, j in bones]] - a
    ap = points[:, None] - a  # (n, S, 2)
    u = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    return np.linalg.norm(ap - u[..., None] * ab, axis=-1).min(axis=1)
