"""``report.md`` and ``report.png`` of a simulated capture and its chain run.

The report answers a planner's questions:

- **what error to expect** from each stage (calibration, sync, 2D, identities, 3D per
  method through the found and the true cameras, knee and hip angles);
- **where**: a top view of the room, coloured by how many cameras see a body's middle, and
  by the 3D error of the people who walked there;
- **what limits the rig**, by rules set before any simulation was looked at:

  - *too few views*: more than 10% of the people's frames in a region that fewer than
    two cameras see;
  - *the calibration*: 3D through the found cameras more than 1.15x that through the true
    ones (then, from people: a longer walk; from a board: more of the volume swept);
  - *a camera too far*: a camera that sees people under 200 px tall (median), where
    detectors lose the wrists and the feet;
  - *a frame rate too low*: joints moving more than 5 cm between two frames of a camera
    (95th percentile), which blurs fast motion and coarsens synchronisation.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rmpl.io.atomic import atomic_path

__all__ = ["limits", "write_report"]

#: The rules of "what limits the rig" (see the module docstring).
FEW_VIEWS_SHARE = 0.10
FOUND_RATIO = 1.15
MIN_PERSON_PX = 200.0
MAX_STEP_M = 0.15


def _f(x, digits: int = 1, unit: str = "") -> str:
    if x is None:
        return "-"
    return f"{x:.{digits}f}{unit}"


def _person_pixels(sim: Path, names: list[str]) -> dict[str, float]:
    """Median height in pixels of the people each camera sees (head top to heels)."""
    out = {}
    for name in names:
        with np.load(sim / "truth" / "projections" / f"{name}.npz") as z:
            uv = z["uv"].astype(float)
        tall = np.nanmax(uv[..., 1], axis=-1) - np.nanmin(uv[..., 1], axis=-1)  # (T, P)
        seen = np.isfinite(uv).all(-1).sum(-1) >= 20
        out[name] = float(np.median(tall[seen])) if seen.any() else float("nan")
    return out


def _joint_steps(sim: Path, fps: np.ndarray) -> float:
    """The 95th percentile of a joint's move between two frames of the slowest camera, m."""
    from rmpl.io.poses import load_poses

    poses = load_poses(sim / "truth" / "poses.npz")
    step = np.linalg.norm(np.diff(poses.points, axis=0), axis=-1) * poses.fps / fps.min()
    step = step[np.isfinite(step)]
    return float(np.percentile(step, 95)) if step.size else 0.0


def _views_at(sim: Path, names: list[str]) -> np.ndarray:
    """Per reference frame and person, how many cameras see most of the body (T, P)."""
    counts = None
    for name in names:
        with np.load(sim / "truth" / "projections" / f"{name}.npz") as z:
            seen = np.isfinite(z["uv"]).all(-1).mean(-1) > 0.5  # (T_v, P)
        counts = seen.astype(int) if counts is None else _add(counts, seen)
    return counts


def _add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    n = min(len(a), len(b))
    return a[:n] + b[:n]


def limits(sim: Path, scores: dict) -> list[str]:
    """The rules' findings, one line each (see the module docstring)."""
    names = list(scores["rig"]["cameras"])
    fps = np.asarray(scores["rig"]["fps"], float)
    found: list[str] = []
    if not (sim / "truth" / "poses.npz").exists():
        return ["No people were filmed: only the board calibration is scored."]
    views = _views_at(sim, names)
    few = float((views < 2).mean()) if views is not None and views.size else 0.0
    if len(names) > 1 and few > FEW_VIEWS_SHARE:
        found.append(
            f"**Too few views**: in {100 * few:.0f}% of the people's frames fewer "
            "than two cameras see the body (the map shows where); add a camera "
            "there or aim one at it."
        )
    key = next((k for k in scores.get("3d", {}) if k.endswith("(found cameras)")), None)
    if key:
        a = scores["3d"][key].get("overall", {}).get("mpjpe_mm")
        b = scores["3d"].get(key.replace("found", "true"), {}).get("overall", {}).get("mpjpe_mm")
        if a and b and a > FOUND_RATIO * b:
            how = (
                "sweep the board through more of the volume, towards every camera"
                if scores["calibration"].get("method") == "board"
                else "walk longer and through the whole volume while calibrating"
            )
            found.append(
                f"**The calibration**: 3D through the found cameras is "
                f"{a / b:.2f}x that through the true ones; {how}."
            )
    for name, px in _person_pixels(sim, names).items():
        if np.isfinite(px) and px < MIN_PERSON_PX:
            found.append(
                f"**{name} is too far**: people are {px:.0f} px tall in its image "
                f"(under {MIN_PERSON_PX:.0f}); move it closer or narrow its lens."
            )
    step = _joint_steps(sim, fps)
    if step > MAX_STEP_M:
        found.append(
            f"**The frame rate**: joints move up to {100 * step:.1f} cm between two "
            f"frames at {fps.min():g} frames/s; film fast motion at a higher rate."
        )
    return found or ["Nothing by these rules: the rig is limited by the detector's own 2D error."]


def _stage_rows(scores: dict) -> list[str]:
    rows = ["| stage | figure |", "|---|---|"]
    cal = scores.get("calibration", {})
    if cal.get("cameras"):
        rows.append(
            f"| calibration ({cal['method']}) | rotation max {_f(cal['rotation_deg']['max'], 2)} "
            f"deg, centre max {_f(cal['centre_mm']['max'], 0)} mm, focal max "
            f"{_f(cal['focal_pct']['max'], 2)}%, scale {_f(cal.get('scale'), 3)} |"
        )
    else:
        rows.append(f"| calibration ({cal.get('method')}) | {cal.get('note')} |")
    sync = scores.get("sync")
    if sync:
        if sync.get("refused"):
            rows.append("| sync | refused (the true offsets were used) |")
        else:
            rows.append(
                f"| sync | largest error {_f(sync['max_abs_error_frames'], 2)} frames; "
                f"whole frames {'all exact' if sync['all_exact'] else 'NOT all exact'} |"
            )
    det = scores.get("detection", {})
    if det:
        e = det.get("error_px", {})
        rows.append(
            f"| 2D detector | recall {_f(100 * (det.get('recall') or 0), 1)}%, precision "
            f"{_f(100 * (det.get('precision') or 0), 1)}%, error median {_f(e.get('median'))} "
            f"px, 90th percentile {_f(e.get('p90'))} px |"
        )
    return rows


def _three_d_rows(scores: dict) -> list[str]:
    rows = [
        "| method (cameras) | MPJPE mm | body MPJPE mm | PCK@100 | PCK@150 | coverage | "
        "tracks / people | IDF1 | knee MAE deg | hip MAE deg |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for key, r in scores.get("3d", {}).items():
        if "overall" not in r:
            rows.append(f"| {key} | {r.get('note')} | | | | | | | | |")
            continue
        o, ident, ang = r["overall"], r["identity"], r.get("angles", {})
        knee = [ang.get(f"knee_flexion_{s}", {}).get("mae_deg") for s in ("left", "right")]
        hip = [ang.get(f"hip_flexion_{s}", {}).get("mae_deg") for s in ("left", "right")]
        knee = [x for x in knee if x is not None]
        hip = [x for x in hip if x is not None]
        rows.append(
            f"| {key} | {_f(o['mpjpe_mm'])} | {_f(r['body']['mpjpe_mm'])} | "
            f"{_f(o['pck'].get('100'))}% | {_f(o['pck'].get('150'))}% | "
            f"{_f(100 * o['coverage'] if o['coverage'] is not None else None)}% | "
            f"{ident['num_tracks']} / {ident['num_people']} | {_f(ident['idf1'], 3)} | "
            f"{_f(np.mean(knee) if knee else None)} | {_f(np.mean(hip) if hip else None)} |"
        )
    return rows


def _cameras(a, rig, xs, ys) -> None:
    """The cameras on a top view: where each stands and where it looks."""
    c = rig.centers
    a.scatter(c[:, 0], c[:, 1], marker="^", c="red", s=60, zorder=3)
    for cam in rig:
        look = cam.R[2, :2]
        a.annotate(cam.name, cam.center[:2], textcoords="offset points", xytext=(4, 4))
        a.arrow(*cam.center[:2], *(0.6 * look / max(np.linalg.norm(look), 1e-9)),
                color="red", width=0.02)  # fmt: skip
    a.set_aspect("equal")
    a.set_xlabel("x (m)")
    a.set_ylabel("y (m)")
    a.set_xlim(xs[0], xs[-1])
    a.set_ylim(ys[0], ys[-1])


def _picture(sim: Path, scores: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rmpl.io.calibration import load_rig
    from rmpl.simulate.rig import volume_of

    rig = load_rig(sim / "truth" / "calibration.toml")
    xs, ys, counts = volume_of(rig)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.6))
    ax = axes[0]
    im = ax.pcolormesh(
        xs, ys, counts, cmap="viridis", shading="nearest", vmin=0, vmax=max(len(rig), 1)
    )
    fig.colorbar(im, ax=ax, label="cameras that see a body's middle (1 m up)")
    ax.set_title("Coverage")
    ax2 = axes[1]
    chain = sim / "chain"
    errs = sorted(chain.glob("errors_*_found.npz")) + sorted(chain.glob("errors_*_true.npz"))
    if errs:
        with np.load(errs[0]) as z:
            hips, err = z["hips"].reshape(-1, 2), z["error"].reshape(-1) * 1000
        ok = np.isfinite(err) & np.isfinite(hips).all(-1)
        sc = ax2.scatter(
            hips[ok, 0],
            hips[ok, 1],
            c=err[ok],
            s=6,
            cmap="magma_r",
            vmin=0,
            vmax=max(np.percentile(err[ok], 95), 1) if ok.any() else 1,
        )
        fig.colorbar(sc, ax=ax2, label="3D error, mm (MPJPE of the person there)")
        ax2.set_title(
            f"3D error where people walked ({errs[0].stem[7:].replace('_', ', ')} cameras)"
        )
    else:
        ax2.set_title("3D error: run with --run")
    for a in axes:
        _cameras(a, rig, xs, ys)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)


def _people(s: dict) -> str:
    n = s["people"]
    who = f"{n} {'person' if n == 1 else 'people'} ({', '.join(s['motion'])})" if n else "nobody"
    return who + (" and a bystander" if s["bystander"] else "")


def write_report(sim: str | Path, scores: dict) -> Path:
    """Write ``report.md`` and ``report.png`` into the simulation folder; returns the md."""
    sim = Path(sim)
    s, rig = scores["settings"], scores["rig"]
    from rmpl.simulate.video import encoder

    lines = [
        "# Simulated capture",
        "",
        f"{len(rig['cameras'])} cameras ({s['rig']['rig']}), {_people(s)}, "
        f"{s['seconds']:g} s; frame rates {', '.join(f'{f:g}' for f in rig['fps'])}; start "
        f"offsets {', '.join(str(int(o)) for o in rig['offset_frames'])} frames; walking area "
        f"radius {rig['area_m']:.1f} m; videos {encoder()}.",
        "",
        "## The error of each stage",
        "",
        *_stage_rows(scores),
        "",
        "## 3D",
        "",
        "MPJPE over the joint set both have (HALPE-26); body: the first 17 (COCO-17); PCK: "
        "% of the true joints within 100 / 150 mm (a missing joint counts as wrong); "
        "coverage: % of the true joints given; through the found cameras the result is moved "
        "into the true world by the cameras' similarity.",
        "",
        *_three_d_rows(scores),
        "",
        "## What limits this rig",
        "",
        *[f"- {x}" for x in limits(sim, scores)],
        "",
        "![coverage and error](report.png)",
        "",
        "## Steps",
        "",
        *[
            f"- {k}: {v.get('status')}" + (f" ({v['line']})" if v.get("line") else "")
            for k, v in scores.get("steps", {}).items()
        ],
        "",
    ]
    _picture(sim, scores, sim / "report.png")
    path = sim / "report.md"
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines), encoding="utf-8")
    with atomic_path(sim / "scores.json") as tmp:
        tmp.write_text(json.dumps(scores, indent=1) + "\n", encoding="utf-8")
    return path
