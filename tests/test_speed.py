"""The faster reading, grouping, writing and model loading of ``rmpl run`` against
straightforward references kept here, and the speed benchmark's output comparison."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rmpl.benchmarks.speed import compare_outputs
from rmpl.data.shelf import load_shelf
from rmpl.errors import InputError
from rmpl.pipeline.association import (
    BODY25_LIMBS,
    Candidates,
    GroupingConfig,
    _limb_connections,
    group_people,
)
from tests.data.test_shelf import shelf_folder  # noqa: F401  (fixture)


def reference_connections(candidates: Candidates, cfg: GroupingConfig) -> list[tuple]:
    """Per limb, every candidate pair by descending affinity (stable), taken one to one."""
    edges = []
    for (a, b), A in zip(candidates.limbs, candidates.affinities, strict=True):
        if A.size == 0:
            continue
        ok_a = candidates.points[a][:, 2] >= cfg.min_part_score
        ok_b = candidates.points[b][:, 2] >= cfg.min_part_score
        S = np.where(ok_a[:, None] & ok_b[None, :] & (A >= cfg.min_affinity), A, -np.inf)
        used_a, used_b = set(), set()
        for k in np.argsort(-S, axis=None, kind="stable"):
            i, j = divmod(int(k), S.shape[1])
            if not np.isfinite(S[i, j]):
                break
            if i not in used_a and j not in used_b:
                used_a.add(i)
                used_b.add(j)
                edges.append((float(S[i, j]), a, i, b, j))
    return edges


def reference_group(candidates: Candidates, cfg: GroupingConfig):
    """The greedy parse on numpy arrays, in BODY_25."""
    J = candidates.num_joints
    owner = [np.full(len(p), -1) for p in candidates.points]
    people = []
    for _, a, i, b, j in sorted(reference_connections(candidates, cfg), key=lambda e: -e[0]):
        pa, pb = owner[a][i], owner[b][j]
        if pa < 0 and pb < 0:
            person = np.full(J, -1)
            person[a], person[b] = i, j
            owner[a][i] = owner[b][j] = len(people)
            people.append(person)
        elif pa >= 0 and pb < 0:
            if people[pa][b] < 0:
                people[pa][b], owner[b][j] = j, pa
        elif pb >= 0 and pa < 0:
            if people[pb][a] < 0:
                people[pb][a], owner[a][i] = i, pb
        elif pa != pb and not ((people[pa] >= 0) & (people[pb] >= 0)).any():
            for k in np.flatnonzero(people[pb] >= 0):
                people[pa][k] = people[pb][k]
                owner[k][people[pb][k]] = pa
            people[pb] = None
    kps, scs = [], []
    for person in people:
        if person is None or (person >= 0).sum() < cfg.min_parts:
            continue
        kp, sc = np.full((J, 2), np.nan), np.zeros(J)
        for k in np.flatnonzero(person >= 0):
            kp[k], sc[k] = candidates.points[k][person[k], :2], candidates.points[k][person[k], 2]
        if sc[person >= 0].mean() >= cfg.min_mean_score:
            kps.append(kp)
            scs.append(sc)
    kp, sc = np.array(kps).reshape(-1, J, 2), np.array(scs).reshape(-1, J)
    order = np.argsort(-sc.sum(-1), kind="stable")
    return kp[order], sc[order]


def random_candidates(rng) -> Candidates:
    """A crowded image: 0-5 candidates per joint, affinities with ties and zeros."""
    points = []
    for _ in range(25):
        n = int(rng.integers(0, 6))
        points.append(np.column_stack([rng.uniform(0, 1000, (n, 2)), rng.uniform(0, 1, n)]))
    aff = []
    for a, b in BODY25_LIMBS:
        A = rng.choice([0.0, 0.05, 0.3, 0.5, 0.7, 0.9], (len(points[a]), len(points[b])))
        aff.append(np.where(rng.random(A.shape) < 0.5, rng.uniform(0, 1, A.shape), A))
    return Candidates(tuple(points), tuple(aff))


@pytest.mark.parametrize("seed", range(4))
def test_grouping_matches_the_reference(seed):
    rng = np.random.default_rng(seed)
    cfg = GroupingConfig()
    for _ in range(25):
        c = random_candidates(rng)
        assert _limb_connections(c, cfg) == reference_connections(c, cfg)
        kp, sc = group_people(c, cfg, output=None)
        ref_kp, ref_sc = reference_group(c, cfg)
        np.testing.assert_array_equal(kp, ref_kp)
        np.testing.assert_array_equal(sc, ref_sc)


def test_an_infinite_affinity_connects_nothing_in_its_limb():
    pts = [np.zeros((0, 3))] * 25
    pts[1], pts[8] = np.array([[1.0, 1, 0.9], [5, 5, 0.9]]), np.array([[1.0, 9, 0.8]])
    aff = [np.zeros((len(pts[a]), len(pts[b]))) for a, b in BODY25_LIMBS]
    aff[0] = np.array([[0.7], [np.inf]])
    c = Candidates(tuple(pts), tuple(aff))
    assert _limb_connections(c, GroupingConfig()) == reference_connections(c, GroupingConfig())


def test_shelf_candidate_counts_are_checked(shelf_folder):  # noqa: F811
    root, _, _ = shelf_folder
    path = root / "detection" / "1.txt"
    tokens = path.read_text().split()
    bad = [*tokens[:2], "1.5", *tokens[3:]]  # frame 0, joint 0: a fractional count
    path.write_text(" ".join(bad))
    with pytest.raises(InputError, match=r"1\.txt.*frame 0, joint 0: candidate count"):
        load_shelf(root)
    path.write_text(" ".join([*tokens[:2], "-1", *tokens[3:]]))
    with pytest.raises(InputError, match=r"1\.txt.*frame 0, joint 0: candidate count"):
        load_shelf(root)
    path.write_text(" ".join([*tokens[:2], "900", *tokens[3:]]))
    with pytest.raises(InputError, match=r"1\.txt.*frame 0, joint 0: 3 x 900 candidates"):
        load_shelf(root)


def test_poses_json_is_the_text_of_json_dump(tmp_path):
    from rmpl.io.poses import Poses3D, _json_doc, save_poses

    rng = np.random.default_rng(0)
    pts = rng.normal(0, 1, (5, 2, 17, 3))
    pts[1, 0] = np.nan
    poses = Poses3D(pts, frames=np.arange(5), fps=30.0)
    save_poses(poses, tmp_path / "p.json")
    with open(tmp_path / "ref.json", "w", encoding="utf-8") as f:
        json.dump(_json_doc(poses), f, allow_nan=False)
    assert (tmp_path / "p.json").read_bytes() == (tmp_path / "ref.json").read_bytes()


def test_onnx_export_is_cached_and_gives_the_same_answer(tmp_path, monkeypatch):
    pytest.importorskip("onnxruntime")
    import torch

    from rmpl.model.export import CACHE_ENV, OnnxLifter, export_key
    from rmpl.model.lifter import PRESETS, RMPL

    torch.manual_seed(0)
    model = RMPL(PRESETS["tiny"]).eval()
    rng = np.random.default_rng(0)
    rays = rng.normal(0, 1, (4, 3, 17, 6)).astype(np.float32)
    rays[..., 3:] /= np.linalg.norm(rays[..., 3:], axis=-1, keepdims=True)
    scores = rng.uniform(0, 1, (4, 3, 17)).astype(np.float32)
    monkeypatch.setenv(CACHE_ENV, "off")
    fresh = OnnxLifter(model)(rays, scores)
    assert not any(tmp_path.iterdir())
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "onnx"))
    first = OnnxLifter(model)(rays, scores)  # exports into the cache
    files = list((tmp_path / "onnx").iterdir())
    assert [f.name for f in files] == [f"{export_key(model)}.onnx"]
    second = OnnxLifter(model)(rays, scores)  # reads it
    np.testing.assert_array_equal(first, fresh)
    np.testing.assert_array_equal(second, fresh)
    with torch.no_grad():  # other weights: another file, never the stale one
        next(model.parameters()).add_(0.1)
    assert export_key(model) != files[0].stem
    OnnxLifter(model)(rays, scores)
    assert len(list((tmp_path / "onnx").iterdir())) == 2
    files[0].write_bytes(b"damaged")  # a damaged file is exported again
    with torch.no_grad():
        next(model.parameters()).sub_(0.1)
    np.testing.assert_array_equal(OnnxLifter(model)(rays, scores), fresh)


def _run_folder(path, points, status):
    path.mkdir(parents=True)
    np.savez(path / "poses.npz", points=points, view_status=status, skeleton=np.array("coco17"))
    (path / "report.json").write_text(json.dumps({"error_px": 4.5, "people": [{"frames": 3}]}))


def test_compare_outputs_tells_equal_from_different(tmp_path):
    rng = np.random.default_rng(0)
    pts = rng.normal(0, 1, (3, 2, 17, 3))
    pts[0, 1] = np.nan
    status = np.zeros((3, 2, 4), np.uint8)
    _run_folder(tmp_path / "a", pts, status)
    _run_folder(tmp_path / "b", pts + 5e-7, status)
    assert compare_outputs(tmp_path / "a", tmp_path / "b") == []
    _run_folder(tmp_path / "c", pts + 2e-6, status)
    assert any("points" in d for d in compare_outputs(tmp_path / "a", tmp_path / "c"))
    moved = pts.copy()
    moved[0, 1] = 0.0
    _run_folder(tmp_path / "d", moved, status + 1)
    diffs = compare_outputs(tmp_path / "a", tmp_path / "d")
    assert any("points" in d for d in diffs) and any("view_status" in d for d in diffs)
    (tmp_path / "b" / "report.json").write_text(json.dumps({"error_px": 4.6, "people": []}))
    diffs = compare_outputs(tmp_path / "a", tmp_path / "b")
    assert any("error_px" in d for d in diffs) and any("people" in d for d in diffs)
