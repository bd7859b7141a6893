"""Example MHP renders with detected (red) and ground-truth (green) COCO-17 keypoints.

Draws ``--count`` (mesh, view) samples made exactly as ``rmpl generate`` makes them (same
config, same code path), and saves them as PNGs no wider than ``--width`` pixels.

  ANNY_CACHE_DIR=~/.cache/rmpl/anny python -m rmpl.benchmarks.mhp_examples configs/mhp.toml \
      --out docs/img --set poses='"../shared/data/cmu_mocap"' --count 4
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rmpl.benchmarks._common import run_main

_BONES = [
    (5, 7),
    (7, 9),
    (6, 8),
    (8, 10),
    (11, 13),
    (13, 15),
    (12, 14),
    (14, 16),
    (5, 6),
    (11, 12),
    (5, 11),
    (6, 12),
    (0, 1),
    (0, 2),
    (1, 3),
    (2, 4),
]


def _draw(image, gt, det, scores, scale):
    from PIL import Image, ImageDraw

    h, w = image.shape[:2]
    im = Image.fromarray(image).resize((round(w * scale), round(h * scale)), Image.LANCZOS)
    d = ImageDraw.Draw(im)
    for pts, color, ok in (
        (gt, (40, 220, 60), np.ones(17, bool)),
        (det, (235, 40, 40), scores > 0),
    ):
        p = (pts + 0.5) * scale - 0.5
        for i, j in _BONES:
            if ok[i] and ok[j]:
                d.line([tuple(p[i]), tuple(p[j])], fill=color, width=2)
        for j in np.flatnonzero(ok):
            x, y = p[j]
            d.ellipse([x - 3, y - 3, x + 3, y + 3], outline=color, width=2)
    return im


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("config")
    ap.add_argument("--out", required=True)
    ap.add_argument("--set", dest="overrides", action="append", default=[])
    ap.add_argument("--count", type=int, default=4)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--prefix", default="mhp_example")
    args = ap.parse_args(argv)

    from rmpl.geometry.camera import project
    from rmpl.synth.body import place_bodies
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.generate import (
        GenerateConfig,
        Worker,
        _draw_poses,
        _prepare_bank,
        _scale_cameras,
        occlude,
    )
    from rmpl.synth.render import random_outfits

    cfg = GenerateConfig.from_toml(args.config, args.overrides)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    bank_dir = Path("/tmp/mhp_examples_bank")
    bank_dir.mkdir(exist_ok=True)
    worker = Worker(cfg, _prepare_bank(cfg, bank_dir))
    rng = np.random.default_rng(cfg.seed)
    n = args.count
    verts, kps, meta, _ = _draw_poses(worker, n, 0, rng)
    verts, kps = place_bodies(
        verts, kps, rng.uniform(-np.pi, np.pi, n), rng.uniform(-cfg.room, cfg.room, (n, 2))
    )
    K, R, t, size = sample_cameras(1, kps[:, 11:13].mean(1).astype(float), cfg.camera_preset, rng)
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[:, None].astype(float), K[:, :, None], R[:, :, None], t[:, :, None])[:, 0]
    images = worker.renderer.render(
        verts, random_outfits(worker.body.vertex_parts, n, rng), K, R, t, size, rng=rng
    )
    if cfg.occlusion_rate > 0:
        occlude(images, proj, cfg.occlusion_rate, cfg.occlusion_size, rng)
    det, scores = worker.detector(images)
    for i in range(n):
        im = _draw(images[i], proj[i], det[i], scores[i], min(1.0, args.width / images[i].shape[1]))
        path = out / f"{args.prefix}_{i}.png"
        im.save(path, optimize=True)
        err = np.linalg.norm(det[i] - proj[i], axis=-1)
        print(
            f"{path}: {meta[i][1]} {meta[i][2]} frame {meta[i][3]}, median error "
            f"{np.nanmedian(err) if np.isfinite(err).any() else float('nan'):.1f} px, "
            f"{int((scores[i] == 0).sum())} missed, {path.stat().st_size // 1024} KB"
        )
    worker.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
