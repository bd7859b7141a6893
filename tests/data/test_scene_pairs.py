"""load_scene_pairs (and load_mhp / ShardSource through it) on multi-person scene sets:
fake scene shards written in the generator's format (always), a tiny real generation
(skipped without anny, EGL and MediaPipe) and the held-out set configs/mhp_scenes_heldout.toml
makes (skipped when absent; its path from RMPL_SCENES_HELDOUT, else data/mhp_scenes_heldout
in the checkout)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from rmpl.data.mhp import ShardSource, load_mhp
from rmpl.data.scenes import is_scene_set, load_scene_pairs, matched_detections
from rmpl.errors import InputError
from rmpl.geometry.camera import project
from rmpl.synth.cameras import sample_cameras
from rmpl.synth.generate import (
    MATCH_TOLERANCE,
    GenerateConfig,
    _write_manifest,
    generate,
    list_shards,
    shard_path,
)
from tests.conftest import synth_ready
from tests.data.test_mhp import _fake_mhp, _ray_distance

_HELDOUT = Path(__file__).resolve().parents[2] / "data" / "mhp_scenes_heldout"


def _fake_scenes(root, scenes=4, views=5, people=(2, 3), slots=4, shards=2, seed=0):
    """Scene shards with exact 'detections': each body is found in a view with probability
    0.7, in a random detector slot; a phantom (matched to no body) sometimes fills a slot;
    bodies of subject '03' and '01' mixed within scenes."""
    rng = np.random.default_rng(seed)
    P, V, N = people[1], views, slots
    cfg = GenerateConfig(num_meshes=scenes * shards, views=V, shard_size=scenes, people=people)
    _write_manifest(root, cfg, "exact", {})
    for s in range(shards):
        k = rng.integers(people[0], P + 1, scenes)
        present = np.arange(P) < k[:, None]  # (S, P)
        where = rng.uniform(-1.5, 1.5, (scenes, P, 1, 3)) * [1, 1, 0]
        joints = rng.normal([0, 0, 1.0], 0.3, (scenes, P, 17, 3)) + where
        joints[~present] = np.nan
        K, R, t, size = sample_cameras(V, np.nanmean(joints, (1, 2)), "universal", rng)
        proj = project(joints[:, None], K[:, :, None, None], R[:, :, None, None],
                       t[:, :, None, None])  # (S, V, P, 17, 2)  # fmt: skip
        kp = np.full((scenes, V, N, 17, 2), np.nan)
        sc = np.zeros((scenes, V, N, 17))
        match = np.full((scenes, V, N), -1, np.int8)
        for i in range(scenes):
            for v in range(V):
                order = rng.permutation(N)
                found = [p for p in range(k[i]) if rng.random() < 0.7]
                for slot, p in zip(order, found, strict=False):
                    kp[i, v, slot], match[i, v, slot] = proj[i, v, p], p
                    sc[i, v, slot] = rng.uniform(0.5, 1.0, 17)
                    sc[i, v, slot, rng.integers(17)] = 0.0  # a miss, stale coordinate
                if len(found) < N and rng.random() < 0.5:  # a phantom: nobody's
                    slot = order[len(found)]
                    kp[i, v, slot], sc[i, v, slot] = rng.uniform(0, 500, (17, 2)), 0.9
        subject = np.where(rng.random((scenes, P)) < 0.5, "03", "01")
        np.savez_compressed(
            shard_path(root, s),
            joints3d=joints.astype(np.float32),
            present=present,
            keypoints=kp.astype(np.float32),
            scores=sc.astype(np.float32),
            match=match,
            projected=proj.astype(np.float32),
            hidden=np.zeros((scenes, V, P, 17), bool),
            K=K,
            R=R,
            t=t,
            size=size.astype(np.int32),
            phenotypes=np.zeros((scenes, P, 6), np.float32),
            subject=np.where(present, subject, ""),
            clip=np.where(present, "c", ""),
            frame=np.where(present, np.arange(P), -1),
            mirrored=np.zeros((scenes, P), bool),
            stats=np.array(json.dumps({})),
        )
    return root


def _reference(root) -> dict[str, np.ndarray]:
    """The pairs by plain loops over scenes, bodies, views and slots."""
    out: dict[str, list] = {"joints3d": [], "keypoints": [], "scores": [], "K": []}
    for path in list_shards(root):
        with np.load(path) as z:
            s = {k: z[k] for k in ("joints3d", "present", "keypoints", "scores", "match", "K")}
        S, V, N, J = s["scores"].shape
        for i in range(S):
            for p in np.flatnonzero(s["present"][i]):
                kp, sc = np.full((V, J, 2), np.nan), np.zeros((V, J))
                for v in range(V):
                    slots = np.flatnonzero(s["match"][i, v] == p)
                    assert len(slots) <= 1  # the generator pairs one slot per body
                    if len(slots):
                        kp[v], sc[v] = s["keypoints"][i, v, slots[0]], s["scores"][i, v, slots[0]]
                out["joints3d"].append(s["joints3d"][i, p])
                out["keypoints"].append(np.where(sc[..., None] > 0, kp, np.nan))
                out["scores"].append(sc)
                out["K"].append(s["K"][i])
    return {k: np.stack(v) for k, v in out.items()}


def _check_pairs(root, d: dict[str, np.ndarray]) -> None:
    """``d`` (load_scene_pairs of ``root``) against the shards: the same bodies and matched
    slots as the plain loops find, views without a match missing, and every matched view's
    2D within the generator's tolerance of the body's projected joints."""
    ref = _reference(root)
    np.testing.assert_array_equal(d["joints3d"], ref["joints3d"])
    np.testing.assert_array_equal(d["scores"], ref["scores"])
    np.testing.assert_array_equal(d["keypoints"], ref["keypoints"])
    np.testing.assert_array_equal(d["K"], ref["K"])
    seen = (d["scores"] > 0).any(-1)  # (M, V)
    assert seen.any() and not seen.all()  # some views have the body's detection, some not
    assert np.isnan(d["keypoints"][~seen]).all()
    assert np.isnan(d["keypoints"][d["scores"] == 0]).all()
    size = np.ptp(d["projected"], axis=-2).max(-1).clip(1.0, None)  # (M, V)
    dist = np.linalg.norm(d["keypoints"] - d["projected"], axis=-1)  # (M, V, J)
    cost = np.nanmedian(np.where(seen[..., None], dist, 0.0), axis=-1) / size
    assert (cost[seen] < MATCH_TOLERANCE).all(), cost[seen].max()


def _check_like_load_mhp(d: dict[str, np.ndarray], single: dict[str, np.ndarray]) -> None:
    """The keys, dtypes and shapes (but M) of a one-body set's load_mhp."""
    assert sorted(d) == sorted(single)
    for k in single:
        assert d[k].dtype.kind == single[k].dtype.kind, k
        assert d[k].shape[1:] == single[k].shape[1:], (k, d[k].shape, single[k].shape)
        assert len(d[k]) == len(d["joints3d"]), k


# ---------------------------------------------------------------------------- fake scenes


def test_matched_detections_puts_each_slot_at_its_body():
    kp = np.arange(4 * 2 * 2, dtype=float).reshape(4, 2, 2)  # N = 4 slots, J = 2
    sc = np.full((4, 2), 0.8)
    got_kp, got_sc = matched_detections(kp, sc, np.array([2, -1, 0, -1], np.int8), 3)
    assert got_kp.shape == (3, 2, 2) and got_sc.shape == (3, 2)
    np.testing.assert_array_equal(got_kp[0], kp[2])
    np.testing.assert_array_equal(got_kp[2], kp[0])
    assert np.isnan(got_kp[1]).all() and (got_sc[1] == 0).all() and (got_sc[[0, 2]] > 0).all()


def test_pairs_of_fake_scenes(tmp_path):
    root = _fake_scenes(tmp_path / "scenes")
    assert is_scene_set(root) and not is_scene_set(tmp_path)
    d = load_scene_pairs(root)
    _check_pairs(root, d)
    present = np.concatenate([np.load(p)["present"] for p in list_shards(root)])
    assert len(d["joints3d"]) == present.sum()
    # Exact detections: every matched keypoint is its body's projection; no phantom enters.
    ok = d["scores"] > 0
    np.testing.assert_allclose(d["keypoints"][ok], d["projected"][ok], atol=1e-3)
    # load_mhp reads the set through load_scene_pairs, in the arrays of a one-body set.
    via = load_mhp(root)
    assert all(np.array_equal(via[k], d[k], equal_nan=d[k].dtype.kind == "f") for k in d)
    _check_like_load_mhp(d, load_mhp(_fake_mhp(tmp_path / "single", views=5)))


def test_subjects_select_bodies_and_joint_sets(tmp_path):
    root = _fake_scenes(tmp_path)
    every = load_scene_pairs(root)
    held = load_scene_pairs(root, exclude_subjects=["03"])
    only = load_scene_pairs(root, subjects=["03"])
    assert set(held["subject"]) == {"01"} and set(only["subject"]) == {"03"}
    assert len(held["joints3d"]) + len(only["joints3d"]) == len(every["joints3d"])
    # Bodies keep their scene's cameras whichever other bodies are dropped.
    first = np.flatnonzero(every["subject"] == "03")
    np.testing.assert_array_equal(only["R"], every["R"][first])
    np.testing.assert_array_equal(only["keypoints"], every["keypoints"][first])
    # A COCO-17 set read as HALPE-26: the nine extra joints missing, the 17 unchanged.
    h = load_scene_pairs(root, joints="halpe26")
    assert h["joints3d"].shape[1:] == (26, 3) and h["keypoints"].shape[2:] == (26, 2)
    assert (h["scores"][..., 17:] == 0).all() and np.isnan(h["joints3d"][:, 17:]).all()
    np.testing.assert_array_equal(h["scores"][..., :17], every["scores"])


def test_shard_source_over_scenes_and_mixed_dirs(tmp_path):
    scenes = _fake_scenes(tmp_path / "scenes", views=5)
    src = ShardSource(scenes, drop_rate=0.0, augment=True, seed=0)
    assert src.num_meshes == len(load_scene_pairs(scenes)["joints3d"]) and src.num_views == 5
    b = src.batch(32, 5)
    assert b.rays.shape == (32, 5, 17, 6) and b.target.shape == (32, 17, 3)
    assert (b.scores > 0).any() and (b.scores == 0).all(-1).any()  # some views without the body
    assert _ray_distance(b).max() < 1e-3  # exact 2D: each ray passes through its body's joint
    # A list may mix a scene set and a one-body set with fewer views (padded).
    single = _fake_mhp(tmp_path / "single", views=3)
    mixed = ShardSource([scenes, single], drop_rate=0.0, augment=False, seed=1, joints="halpe26")
    assert mixed.num_meshes == src.num_meshes + 12 and mixed.num_views == 5
    b = mixed.batch(16, 4)
    assert b.rays.shape == (16, 4, 26, 6) and _ray_distance(b).max() < 1e-3


def test_bad_scene_input_names_the_problem(tmp_path):
    with pytest.raises(InputError, match="manifest.json"):
        load_scene_pairs(tmp_path / "nowhere")
    single = _fake_mhp(tmp_path / "single")
    with pytest.raises(InputError, match=r"field 'format'.*single-body set"):
        load_scene_pairs(single)
    root = _fake_scenes(tmp_path / "scenes", shards=1)
    with pytest.raises(InputError, match="field 'subject'"):
        load_scene_pairs(root, subjects=["99"])
    with pytest.raises(InputError, match="field 'subject'"):
        load_mhp(root, exclude_subjects=["01", "03"])  # through the dispatch too
    with np.load(shard_path(root, 0)) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(shard_path(root, 0), **{**arrays, "match": np.full_like(arrays["match"], 7)})
    with pytest.raises(InputError, match=r"shard_00000\.npz: field 'match': expected body"):
        load_scene_pairs(root)
    np.savez(shard_path(root, 0), **{k: v for k, v in arrays.items() if k != "match"})
    with pytest.raises(InputError, match="field 'match'.*missing"):
        load_scene_pairs(root)
    shard_path(root, 0).unlink()
    with pytest.raises(InputError, match="shard_"):
        load_scene_pairs(root)
    manifest = json.loads((root / "manifest.json").read_text())
    (root / "manifest.json").write_text(json.dumps({**manifest, "joints": ["a", "b"]}))
    with pytest.raises(InputError, match="field 'joints'"):
        load_scene_pairs(root)


# ---------------------------------------------------------------------------- real scenes


@pytest.fixture(scope="module")
def tiny_scenes(tmp_path_factory):
    """Three HALPE-26 scenes of 2-3 bodies, 3 views, rendered and detected for real."""
    synth_ready("anny", "moderngl", "mediapipe")
    out = tmp_path_factory.mktemp("scenes") / "run"
    cfg = GenerateConfig.from_dict(
        {"poses": "random", "num_meshes": 3, "views": 3, "shard_size": 2, "batch_size": 1,
         "camera_preset": "h36m", "image_size": [480, 480], "seed": 17, "people": [2, 3],
         "detector": "blazepose-multi-static", "joints": "halpe26"}
    )  # fmt: skip
    generate(cfg, out, progress=False)
    return out


def test_pairs_of_real_scenes(tiny_scenes, tmp_path):
    d = load_scene_pairs(tiny_scenes)
    _check_pairs(tiny_scenes, d)
    assert d["joints3d"].shape[1:] == (26, 3) and d["keypoints"].shape[1:] == (3, 26, 2)
    # The matched detections lie on their bodies: 10 px median at this image size, as the
    # generator's tests state for MediaPipe's confident keypoints.
    ok = d["scores"] > 0.5
    err = np.linalg.norm(d["keypoints"] - d["projected"], axis=-1)[ok]
    assert ok.sum() >= 50 and np.median(err) < 10.0, (ok.sum(), np.median(err))
    _check_like_load_mhp(d, load_mhp(_fake_mhp(tmp_path, views=3), joints="halpe26"))
    b = ShardSource(tiny_scenes, seed=0).batch(8, 3)
    assert b.rays.shape == (8, 3, 26, 6) and np.isfinite(b.rays).all()


@pytest.fixture
def scenes_heldout() -> Path:
    root = Path(os.environ.get("RMPL_SCENES_HELDOUT", _HELDOUT))
    if not (root / "manifest.json").is_file():
        pytest.skip(f"no scene set at {root} (configs/mhp_scenes_heldout.toml makes it; "
                    "set RMPL_SCENES_HELDOUT)")  # fmt: skip
    return root


def test_pairs_of_the_heldout_scenes(scenes_heldout, tmp_path):
    d = load_scene_pairs(scenes_heldout)
    _check_pairs(scenes_heldout, d)
    V = d["scores"].shape[1]
    _check_like_load_mhp(d, load_mhp(_fake_mhp(tmp_path, views=V)))
    b = ShardSource(scenes_heldout, seed=0, joints="halpe26").batch(16, min(V, 5))
    assert b.rays.shape == (16, min(V, 5), 26, 6) and np.isfinite(b.rays).all()


def test_bodies_no_drawn_view_detects_are_left_out_of_the_loss(tmp_path):
    """A training batch's body with no keypoint in its drawn views gets a NaN target (the
    NaN-aware loss skips it); validation batches keep every target."""
    src = ShardSource(_fake_scenes(tmp_path / "scenes", views=5), drop_rate=0.0, seed=0)
    b = src.batch(64, 1)
    empty = ~(b.scores > 0).any((1, 2))
    assert empty.any() and (~empty).any()
    assert np.isnan(b.target[empty]).all() and np.isfinite(b.target[~empty]).all()
    v = src.batch(64, 1, train=False)
    assert np.isfinite(v.target).all()
