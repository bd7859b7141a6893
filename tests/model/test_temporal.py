"""The temporal lifter: masking, invariances, time, windows, training and checkpoints."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rmpl.model.lifter import PRESETS, RMPL
from rmpl.model.temporal import TemporalConfig, TemporalRMPL, interpolate_missing

SHIPPED = {"interpolate_valid": True, "body_token": True, "fused_start": True}


def _model(window: int = 8, seed: int = 0, head: bool = True, **flags) -> TemporalRMPL:
    torch.manual_seed(seed)
    frame = RMPL(PRESETS["tiny"].with_(robust_anchor=2))
    with torch.no_grad():  # a per-frame model that is not just the ray intersections
        frame.head.weight.normal_(0, 0.02)
    m = TemporalRMPL(frame, TemporalConfig(dim=32, depth=2, window=window, **flags))
    if head:  # a temporal head that is not zero, so that the temporal stage matters
        with torch.no_grad():
            m.head.weight.normal_(0, 0.05)
    return m.eval()


def _inputs(B=2, T=8, V=3, seed=1):
    g = torch.Generator().manual_seed(seed)
    origin = torch.randn(B, 1, V, 1, 3, generator=g) * 3
    target = torch.randn(B, T, 1, 17, 3, generator=g) * 0.3 + torch.tensor([0, 0, 1.0])
    d = target - origin
    d = d + 0.01 * torch.randn(d.shape, generator=g)
    d = d / d.norm(dim=-1, keepdim=True)
    rays = torch.cat([origin.expand(B, T, V, 17, 3), d], -1)
    scores = 0.5 + 0.5 * torch.rand(B, T, V, 17, generator=g)
    times = torch.arange(T, dtype=torch.float32)[None].repeat(B, 1) / 25
    return rays, scores, times


def test_untrained_temporal_model_is_the_per_frame_model():
    m = _model(head=False)
    rays, scores, times = _inputs()
    points, sigma = m(rays, scores, times)
    B, T, V = rays.shape[:3]
    frame = m.frame_model(rays.reshape(B * T, V, 17, 6), scores.reshape(B * T, V, 17))
    assert torch.allclose(points, frame.view(B, T, 17, 3), atol=1e-5)
    assert torch.allclose(sigma, torch.full_like(sigma, 0.05))


@pytest.mark.parametrize("flags", [{}, SHIPPED], ids=["first", "shipped"])
def test_masked_content_changes_nothing(flags):
    """What lies under a zero score (a view of a frame, or a whole frame) is never read."""
    m = _model(**flags)
    rays, scores, times = _inputs()
    ref, ref_s = m(rays, scores, times)
    masked_rays, masked_scores = rays.clone(), scores.clone()
    masked_scores[0, 3, 1] = 0  # a view in one frame
    masked_scores[1, 5] = 0  # a whole frame
    base, base_s = m(masked_rays, masked_scores, times)
    garbage = masked_rays.clone()
    garbage[0, 3, 1] = torch.randn_like(garbage[0, 3, 1]) * 100
    garbage[1, 5] = float("nan")
    out, out_s = m(garbage, masked_scores, times)
    assert torch.allclose(out, base, atol=1e-6) and torch.allclose(out_s, base_s, atol=1e-6)
    assert not torch.allclose(base, ref, atol=1e-4)  # the mask itself does change the answer


@pytest.mark.parametrize("flags", [{}, SHIPPED], ids=["first", "shipped"])
def test_view_order_does_not_matter(flags):
    m = _model(**flags)
    rays, scores, times = _inputs(V=4)
    perm = torch.tensor([2, 0, 3, 1])
    a, sa = m(rays, scores, times)
    b, sb = m(rays[:, :, perm], scores[:, :, perm], times)
    assert torch.allclose(a, b, atol=1e-5) and torch.allclose(sa, sb, atol=1e-5)


@pytest.mark.parametrize("flags", [{}, SHIPPED], ids=["first", "shipped"])
def test_a_missing_frame_does_not_turn_its_neighbours_nan_and_is_filled(flags):
    m = _model(**flags)
    rays, scores, times = _inputs(T=8)
    scores[:, 4] = 0
    rays[:, 4] = float("nan")
    points, sigma = m(rays, scores, times)
    assert torch.isfinite(points).all() and torch.isfinite(sigma).all()


@pytest.mark.parametrize("flags", [{}, SHIPPED], ids=["first", "shipped"])
def test_a_window_with_nothing_seen_is_nan(flags):
    m = _model(**flags)
    rays, scores, times = _inputs(B=2)
    scores[1] = 0
    points, sigma = m(rays, scores, times)
    assert torch.isnan(points[1]).all() and torch.isnan(sigma[1]).all()
    assert torch.isfinite(points[0]).all()


def test_time_origin_does_not_matter_but_the_rate_does():
    m = _model()
    rays, scores, times = _inputs()
    a, _ = m(rays, scores, times)
    b, _ = m(rays, scores, times + 123.0)
    c, _ = m(rays, scores, times * 4)
    assert torch.allclose(a, b, atol=1e-4)
    assert not torch.allclose(a, c, atol=1e-4)


def test_interpolate_missing_is_linear_in_time_and_holds_the_ends():
    T = 6
    x = torch.arange(T, dtype=torch.float32).view(1, T, 1, 1).expand(1, T, 1, 3).clone()
    ok = torch.tensor([[False, True, False, False, True, False]])[..., None]
    times = torch.tensor([[0.0, 1.0, 2.0, 4.0, 5.0, 6.0]])
    out = interpolate_missing(x * 10, ok, times)[0, :, 0, 0]
    # frame 2 at t=2 between t=1 (10) and t=5 (40): 10 + 30 * 1/4; frame 3 at t=4: 10 + 30 * 3/4
    assert out.tolist() == pytest.approx([10.0, 10.0, 17.5, 32.5, 40.0, 40.0])
    none = interpolate_missing(x, torch.zeros(1, T, 1, dtype=torch.bool), times)
    assert (none == 0).all()


def test_overfits_one_batch():
    torch.manual_seed(0)
    m = _model(head=False).train()
    rays, scores, times = _inputs(B=2, T=8)
    target = torch.randn(2, 8, 17, 3) * 0.05 + m(rays, scores, times)[0].detach()
    opt = torch.optim.Adam([p for p in m.parameters() if p.requires_grad], lr=3e-3)
    first = None
    for _ in range(300):
        p, _ = m(rays, scores, times)
        loss = (p - target).norm(dim=-1).mean()
        first = first if first is not None else loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.3 * first
    assert all(not p.requires_grad for p in m.frame_model.parameters())


def test_config_checks():
    with pytest.raises(ValueError, match="window"):
        TemporalConfig(window=1)
    with pytest.raises(ValueError, match="unknown"):
        TemporalConfig.from_dict({"windw": 3})
    with pytest.raises(ValueError, match="sigma_scale"):
        TemporalConfig(sigma_scale=0)


def test_onnx_encoder_matches_torch():
    pytest.importorskip("onnxruntime")
    m = _model()
    rays, scores, times = _inputs()
    with torch.no_grad():
        a, sa = m(rays, scores, times)
        m.use_onnx()
        b, sb = m(rays, scores, times)
    assert np.allclose(a.numpy(), b.numpy(), atol=2e-3)
    assert np.allclose(sa.numpy(), sb.numpy(), rtol=2e-2, atol=1e-4)


def test_fused_start_puts_a_one_view_joint_on_its_ray_at_the_interpolated_depth():
    from rmpl.model.temporal import _fused_start

    B, T, J = 1, 5, 1
    times = torch.arange(T, dtype=torch.float32)[None]
    answer = torch.zeros(B, T, J, 3)
    answer[0, :, 0] = torch.tensor([[0.0, 0, 1], [9, 9, 9], [9, 9, 9], [9, 9, 9], [0, 0, 1]])
    flags = torch.zeros(B, T, J, 3)
    flags[0, [0, 4], 0, 0] = 1  # two views agree on the joint in frames 0 and 4
    flags[..., 2] = 1  # every frame sees it
    okj = torch.ones(B, T, J, dtype=torch.bool)
    ray = torch.zeros(B, T, J, 6)
    ray[..., :3] = torch.tensor([3.0, 0, 1])  # a camera at x = 3 looking along -x
    ray[..., 3:] = torch.tensor([-1.0, 0, 0])
    ray[0, 2, 0, :3] = torch.tensor([3.0, 0.2, 1])  # in frame 2 the ray passes y = 0.2
    start, extra = _fused_start(answer, answer.clone(), flags, okj, ray, times)
    assert torch.allclose(start[0, 0, 0], answer[0, 0, 0])  # valid frames keep their answer
    assert torch.allclose(start[0, 2, 0], torch.tensor([0.0, 0.2, 1.0]), atol=1e-6)
    assert extra[0, :, 0, 0].tolist() == pytest.approx([0, 1, 2, 1, 0])  # seconds to a valid frame
    assert (extra[..., 1] == 1).all()
    flags[..., 0] = 0  # no frame triangulates the joint: the per-frame answer stays
    start, extra = _fused_start(answer, answer.clone(), flags, okj, ray, times)
    assert torch.equal(start, answer) and (extra[..., 1] == 0).all()
