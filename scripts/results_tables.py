"""Print the compact tables of docs/results.md from the CSVs that scripts/results.sh wrote.

Usage: python scripts/results_tables.py [RESULTS_DIR [OCCLUSION_PLOT.png]]
(default: results; with a second argument it also draws MPJPE vs occlusion on the renders)
   or: python scripts/results_tables.py RESULTS_DIR --by-run NAME...
(common-joint MPJPE, or for rec_* held-out-view pixels, per method and view count)

Each block is headed by the results folder it reads; a folder that is missing is skipped.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

ROOT = Path(sys.argv[1] if len(sys.argv) > 1 else "results")


def rows(name: str) -> list[dict] | None:
    path = ROOT / name / "results.csv"
    if not path.is_file():
        print(f"\n({path} missing)\n")
        return None
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def num(x: str, digits: int = 1) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "—"
    return "—" if v != v else f"{v:.{digits}f}"


def shelf_views() -> None:
    r = rows("shelf_views")
    if r is None:
        return
    print("\n### shelf_views\n")
    print("| views | method | MPJPE | PA-MPJPE | PCK@150 | coverage | common | PCP mean |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for x in r:
        if x["views"].startswith("1 ") and x["method"] != "rmpl":
            continue
        print(
            f"| {x['views']} | {x['method']} | {num(x['mpjpe'])} | {num(x['pa_mpjpe'])} | "
            f"{num(x['pck'])} | {num(x['coverage'])} | {num(x['mpjpe_common'])} | "
            f"{num(x['pcp_mean'])} |"
        )


def sweep(name: str, key: str) -> None:
    r = rows(name)
    if r is None:
        return
    print(f"\n### {name}\n")
    conds = list(dict.fromkeys(x[key] for x in r))
    print(
        "| views | method | "
        + " | ".join(conds)
        + " | common (last) | PCK (last) | coverage (last) |"
    )
    print("|---|---|" + "---:|" * (len(conds) + 3))
    for v in dict.fromkeys(x["views"] for x in r):
        for m in dict.fromkeys(x["method"] for x in r):
            sel = {x[key]: x for x in r if x["views"] == v and x["method"] == m}
            last = sel[conds[-1]]
            cells = " | ".join(num(sel[c]["mpjpe"]) for c in conds)
            print(
                f"| {v} | {m} | {cells} | {num(last['mpjpe_common'])} | {num(last['pck'])} | "
                f"{num(last['coverage'])} |"
            )


def synthetic_views() -> None:
    r = rows("synthetic_views")
    if r is None:
        return
    print("\n### synthetic_views (MPJPE | coverage | common)\n")
    for v in dict.fromkeys(x["views"] for x in r):
        cells = [
            f"{x['method']}: {num(x['mpjpe'])} | {num(x['coverage'])} | {num(x['mpjpe_common'])}"
            for x in r
            if x["views"] == v
        ]
        print(f"- {v} views: " + "; ".join(cells))


def sphere() -> None:
    r = rows("sphere")
    if r is None:
        return
    print("\n### sphere (common joints: triangulate / robust / rmpl)\n")
    angles = (10, 20, 30, 60, 90, 120, 150, 170, 180)
    print("| height (m) | " + " | ".join(f"{a}°" for a in angles) + " |")
    print("|---|" + "---|" * len(angles))
    for h in dict.fromkeys(float(x["height"]) for x in r):
        cells = []
        for a in angles:
            d = {
                x["method"]: x["mpjpe_common"]
                for x in r
                if float(x["height"]) == h and abs(float(x["angle"]) - a) < 1e-6
            }
            cells.append(" / ".join(num(d.get(m), 0) for m in ("triangulate", "robust", "rmpl")))
        print(f"| {h:g} | " + " | ".join(cells) + " |")


def mhp_occlusion() -> None:
    sets = {"p = 0": "mhp_val", "p = 0.2": "mhp_val_occ0.2", "p = 0.4": "mhp_val_occ0.4"}
    data = {k: rows(v) for k, v in sets.items()}
    if any(v is None for v in data.values()):
        return
    print("\n### MHP renders, common joints | PCK@150\n")
    print("| views | method | " + " | ".join(sets) + " |")
    print("|---|---|" + "---|" * len(sets))
    methods = list(dict.fromkeys(x["method"] for x in data["p = 0"]))
    for v in ("2", "3", "4", "5"):
        for m in methods:
            cells = []
            for k in sets:
                x = [y for y in data[k] if y["views"] == v and y["method"] == m][0]
                cells.append(f"{num(x['mpjpe_common'])} \\| {num(x['pck'])}")
            print(f"| {v} | {m} | " + " | ".join(cells) + " |")


def occlusion_plot(out: Path) -> None:
    """MPJPE on common joints vs the occlusion-square probability on the MHP renders."""
    from rmpl.evaluate.plots import sweep_plot

    sets = {0.0: "mhp_val", 0.2: "mhp_val_occ0.2", 0.4: "mhp_val_occ0.4"}
    data = {p: rows(name) for p, name in sets.items()}
    if any(v is None for v in data.values()):
        return
    curves = {}
    for m in ("triangulate", "robust", "rmpl"):
        for v in ("2", "5"):
            ys = [
                float(
                    [x for x in data[p] if x["views"] == v and x["method"] == m][0]["mpjpe_common"]
                )
                for p in sets
            ]
            curves[f"{m} | {v} views"] = (list(sets), ys)
    sweep_plot(
        curves,
        out,
        "probability of a black 50 px square over each joint, before MediaPipe",
        "MPJPE, common joints (mm)",
        "MHP renders of held-out motion: MPJPE vs occlusion",
    )
    print(f"\nwrote {out}")


def simple(name: str) -> None:
    r = rows(name)
    if r is None:
        return
    print(f"\n### {name}\n")
    for x in r:
        extra = f" | PCP {num(x['pcp_mean'])}" if "pcp_mean" in x else ""
        print(
            f"- {x['views']} | {x.get('calib_noise', '')} | {x['method']}: MPJPE "
            f"{num(x['mpjpe'])} | PA {num(x['pa_mpjpe'])} | PCK {num(x['pck'])} | coverage "
            f"{num(x['coverage'])} | common {num(x['mpjpe_common'])}{extra}"
        )


def by_run(name: str, column: str = "mpjpe_common") -> None:
    """One row per method, one column per view count: the candidate comparisons."""
    r = rows(name)
    if r is None:
        return
    views = list(dict.fromkeys(x["views"] for x in r))
    methods = list(dict.fromkeys(x["method"] for x in r))
    value = {
        (x["views"], x["method"]): x[column]
        for x in r
        if x.get("dropout", "0") in ("0", "0.0000", "")
    }
    print(f"\n### {name} ({column})\n")
    print("| method | " + " | ".join(views) + " |")
    print("|---|" + "---:|" * len(views))
    for m in methods:
        print(f"| {m} | " + " | ".join(num(value.get((v, m))) for v in views) + " |")


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[2] == "--by-run":
        for name in sys.argv[3:]:
            by_run(name, "px_common" if name.startswith("rec_") else "mpjpe_common")
        sys.exit()
    shelf_views()
    simple("shelf_e2e/eval")
    sweep("shelf_dropout", "dropout")
    sweep("shelf_calib", "calib_noise")
    synthetic_views()
    sphere()
    for name in ("campus_fixture", "panoptic_fixture", "h36m_fixture"):
        simple(name)
    mhp_occlusion()
    if len(sys.argv) > 2:
        occlusion_plot(Path(sys.argv[2]))
