"""``rmpl simulate --run``: the user's chain on a simulated recording, scored stage by stage.

The commands are the ones a user types (``rmpl.cli.main``, so a simulated run and a real
one never differ), into ``<simulation>/chain/``:

1. **2D**: the shipped detector on every video, as ``rmpl run --videos`` runs it (once,
   cached in ``chain/keypoints2d.npz``; every later step reads it);
2. **calibration**:
   - with a board sweep: ``rmpl calibrate --board SPEC --extrinsics board/*.mp4`` (lenses
     and poses from the sweep alone);
   - else from people: ``rmpl sync`` without a calibration (whole frames, from the 2D
     motion; skipped when it refuses), then ``rmpl calibrate --from-people`` with the true
     lenses (a user calibrates lenses once, from a board or the maker's figures) and that
     sync;
3. **sync**: ``rmpl sync --calib`` through the found cameras;
4. **3D**: ``rmpl run`` through the found cameras and sync, and through the true ones
   (the same 2D), for each method asked.

A step whose output exists is not run again (resume). A step that refuses (an
``InputError``: a recording that does not decide) is recorded with its one line; the
later steps use the truth in its place and say so, so every stage is still scored.

Each stage is scored by :mod:`rmpl.simulate.score` and everything lands in
``chain/scores.json``; :mod:`rmpl.simulate.report` writes ``report.md`` and ``report.png``.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path

__all__ = ["run_chain", "METHODS"]

log = logging.getLogger(__name__)

#: Methods run by default: rmpl's default model, and robust triangulation.
METHODS = ("rmpl", "robust")


def _cli(argv: list[str]) -> tuple[int, str | None]:
    """Run one rmpl command; (exit status, the refusal's line or None)."""
    from rmpl.cli import main

    log.info("$ rmpl %s", " ".join(argv))
    try:
        return int(main(argv) or 0), None
    except SystemExit as e:  # argparse
        return int(e.code or 0), f"exit {e.code}"
    except InputError as e:
        return 2, str(e)


def _main_refusal(argv: list[str]) -> tuple[int, str | None]:
    """Like :func:`_cli`, catching the command's own one-line refusals too (rmpl's main
    prints an InputError and returns 2)."""
    import contextlib
    import io

    buf = io.StringIO()
    handler = logging.StreamHandler(buf)
    handler.setLevel(logging.ERROR)
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        with contextlib.redirect_stderr(io.StringIO()) as err:
            code, line = _cli(argv)
    finally:
        root.removeHandler(handler)
    if code != 0 and line is None:
        text = (buf.getvalue() + err.getvalue()).strip().splitlines()
        line = text[-1] if text else f"exit {code}"
    return code, line


def _detect(sim: Path, chain: Path, rig, fps: np.ndarray, detector: str | None) -> Path:
    """The 2D of every video, cached in ``chain/keypoints2d.npz``."""
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    cache = chain / "keypoints2d.npz"
    videos = [str(sim / "videos" / f"{n}.mp4") for n in rig.names]
    spec = InputSpec(
        str(sim / "truth" / "calibration.toml"), None, videos, detector=detector, sync="find"
    )
    load_inputs(spec, cache)
    return cache


def _step(record: dict, name: str, out: Path, argv: list[str]) -> bool:
    """Run a step unless ``out`` exists; record its status. True when ``out`` exists."""
    t0 = time.perf_counter()
    if out.exists():
        record[name] = {"status": "done before", "argv": argv}
        return True
    code, line = _main_refusal(argv)
    ok = out.exists()
    record[name] = {
        "status": "ok" if ok else "refused",
        "exit": code,
        "line": line,
        "seconds": round(time.perf_counter() - t0, 1),
        "argv": argv,
    }
    if not ok:
        log.warning("%s refused: %s", name, line)
    return ok


def _fps_args(fps: np.ndarray) -> list[str]:
    return ["--fps", *[f"{f:g}" for f in fps]]


def _lenses_only(sim: Path, chain: Path) -> Path:
    """The true lenses with the cameras' poses forgotten (what a user brings to a
    calibration from people): ``chain/lenses.toml``."""
    from rmpl.geometry.camera import Camera, Rig
    from rmpl.io.calibration import load_rig, save_rig

    path = chain / "lenses.toml"
    if not path.exists():
        rig = load_rig(sim / "truth" / "calibration.toml")
        cams = [
            Camera(c.K, np.eye(3), np.array([0.0, 0.0, 5.0 + v]), c.dist, c.size, c.name)
            for v, c in enumerate(rig)
        ]
        save_rig(Rig(tuple(cams)), path)
    return path


def _calibrate(sim: Path, chain: Path, doc: dict, kp: Path, fps: np.ndarray, record: dict):
    """The found calibration's path, or None when the step refused."""
    found = chain / "calibration.toml"
    board = doc["settings"].get("board")
    if board:
        videos = [str(sim / "board" / f"{n}.mp4") for n in doc["rig"]["cameras"]]
        argv = [
            "calibrate",
            "--board",
            board,
            "--extrinsics",
            *videos,
            "--out",
            str(found),
            "--no-progress",
        ]
        return found if _step(record, "calibrate (board)", found, argv) else None
    motion_sync = chain / "sync_motion.json"
    _step(
        record,
        "sync (2D motion)",
        motion_sync,
        ["sync", "--keypoints", str(kp), *_fps_args(fps), "--out", str(motion_sync)],
    )
    if not motion_sync.exists() and np.ptp(fps) > 0:
        # the command refuses videos at different rates without --sync (frame i of each
        # view is another instant); from the 2D cache it cannot tell, so the chain says it
        record["calibrate (people)"] = {
            "status": "refused",
            "line": "cameras at different frame rates need their offsets (rmpl sync) before "
            "a calibration from people, and the 2D motion did not decide them",
        }
        return None
    argv = [
        "calibrate",
        "--from-people",
        "--calib",
        str(_lenses_only(sim, chain)),
        "--keypoints",
        str(kp),
        "--out",
        str(found),
        "--no-progress",
    ]
    if motion_sync.exists():
        argv += ["--sync", str(motion_sync)]
    return found if _step(record, "calibrate (people)", found, argv) else None


def _runs(sim: Path, chain: Path, kp: Path, calib: Path, sync: Path, fps, cameras: int,
          methods, record: dict) -> dict:  # fmt: skip
    """``rmpl run`` per method through the found and the true cameras: {(method, which):
    poses.npz}."""
    sync_arg = sync if sync.exists() else sim / "truth" / "sync.json"
    runs = {}
    for method in methods:
        for which, cal, syn in (
            ("found", calib, sync_arg),
            ("true", sim / "truth" / "calibration.toml", sim / "truth" / "sync.json"),
        ):
            out = chain / f"run_{method}_{which}"
            argv = ["run", "--calib", str(cal), "--keypoints", str(kp), "--fps", f"{fps[0]:g}"]
            argv += ["--out", str(out), "--no-pictures", "--formats", "npz"]
            if cameras > 1:
                argv += ["--sync", str(syn)]
            if method != "rmpl":
                argv += ["--method", method]
            _step(record, f"run {method} ({which} cameras)", out / "poses.npz", argv)
            runs[(method, which)] = out / "poses.npz"
    return runs


def run_chain(sim: str | Path, methods=METHODS, detector: str | None = None) -> dict:
    """Run and score the chain on the simulation in ``sim`` (see the module docstring).

    Returns:
        ``chain/scores.json``'s document.
    """
    from rmpl.io.calibration import load_rig

    sim = Path(sim)
    doc = json.loads((sim / "simulate.json").read_text(encoding="utf-8"))
    if not doc.get("finished"):
        raise InputError(
            sim / "simulate.json",
            "finished",
            "a complete simulation (run rmpl simulate again to finish it)",
            "incomplete",
        )
    chain = sim / "chain"
    chain.mkdir(exist_ok=True)
    truth_rig = load_rig(sim / "truth" / "calibration.toml")
    if len(truth_rig) < 2 and not doc["settings"].get("board"):
        raise InputError(
            sim,
            "--run",
            "two or more cameras to calibrate from people (one "
            "camera has no other to be placed against)",
            len(truth_rig),
        )
    fps = np.asarray(doc["rig"]["fps"], float)
    record: dict = {}
    from rmpl.simulate.scoring import score_all

    if not (sim / "truth" / "poses.npz").exists():  # a board sweep alone: its calibration
        found = _calibrate(sim, chain, doc, None, fps, record)
        return _save(chain, score_all(sim, chain, doc, found, None, {}, record))
    t0 = time.perf_counter()
    kp = _detect(sim, chain, truth_rig, fps, detector)
    record["detect"] = {"status": "ok", "seconds": round(time.perf_counter() - t0, 1)}
    found = _calibrate(sim, chain, doc, kp, fps, record) if len(truth_rig) > 1 else None
    calib = found or sim / "truth" / "calibration.toml"
    sync = chain / "sync.json"
    if len(truth_rig) > 1:
        argv = ["sync", "--calib", str(calib), "--keypoints", str(kp), *_fps_args(fps)]
        _step(record, "sync (through the cameras)", sync, argv + ["--out", str(sync)])
    runs = _runs(sim, chain, kp, calib, sync, fps, len(truth_rig), methods, record)
    scores = score_all(sim, chain, doc, found, sync if sync.exists() else None, runs, record)
    return _save(chain, scores)


def _save(chain: Path, scores: dict) -> dict:
    with atomic_path(chain / "scores.json") as tmp:
        tmp.write_text(json.dumps(scores, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return scores
