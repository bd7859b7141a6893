"""Atomic writes: a failed or killed run never leaves a partial output behind.

Two levels, both described in docs/reliability.md:

- :func:`atomic_path`, one file: written under a temporary name in the same folder,
  ``.<name>.<pid>-<token>.rmpl-part<suffix>``, then renamed over the target. A process
  killed mid-write leaves that temporary file; the next atomic write into the same folder
  (any rmpl command) removes the temporary files of processes that no longer run, and
  says so at WARNING.
- :func:`staged_folder`, a set of files that changes as a unit (the outputs of
  ``rmpl run``): every file is written into ``<folder>/.rmpl-staging.<pid>/``; once all are
  complete a journal ``<folder>/.rmpl-commit.json`` lists what to move in and which of the
  previous set's files to remove, the moves are made, and the journal is deleted.
  :func:`recover_folder` (called by the next run, and by :func:`finish_commit` from readers)
  rolls an interrupted commit forward from its journal, and removes a staging folder that
  never got a journal (the old set is then intact). Files that rmpl did not write in this
  folder are never touched.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import secrets
import shutil
from collections.abc import Iterator
from pathlib import Path

from rmpl.errors import InputError

__all__ = [
    "MANIFEST",
    "atomic_path",
    "clean_stale_parts",
    "finish_commit",
    "recover_folder",
    "staged_folder",
]

log = logging.getLogger(__name__)

PART_TAG = ".rmpl-part"
JOURNAL = ".rmpl-commit.json"
MANIFEST = ".rmpl-outputs.json"
STAGING = ".rmpl-staging."
_PART = re.compile(r"^\..+\.(\d+)-[0-9a-f]+" + re.escape(PART_TAG))
# Temporary files of rmpl before 0.1.1: tempfile.mkstemp(prefix=".<name>.", suffix=".part<ext>").
_LEGACY_PART = re.compile(r"^\..+\.[a-z0-9_]{8}\.part(\.[A-Za-z0-9]+)?$")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # somebody else's process
        return True
    except OSError:
        return False
    return True


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def clean_stale_parts(folder: str | Path) -> int:
    """Remove the temporary files that killed writers left in ``folder``; returns how many.

    A temporary file whose writer still runs is kept.
    """
    folder = Path(folder)
    removed = 0
    try:
        entries = list(folder.iterdir())
    except OSError:
        return 0
    for p in entries:
        m = _PART.match(p.name)
        stale = (m is not None and not _alive(int(m.group(1)))) or bool(_LEGACY_PART.match(p.name))
        if stale:
            _remove(p)
            removed += 1
    if removed:
        log.warning("removed %d temporary files of interrupted writes in %s", removed, folder)
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it into place only on success.

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(d / "a.txt") as tmp:
    ...     _ = tmp.write_text("hi")
    >>> (d / "a.txt").read_text(), [p.name for p in d.iterdir()]
    ('hi', ['a.txt'])
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_dir():
        raise InputError(path, None, "an output file path", "an existing directory")
    clean_stale_parts(path.parent)
    token = secrets.token_hex(4)
    tmp_path = path.parent / f".{path.name}.{os.getpid()}-{token}{PART_TAG}{path.suffix}"
    tmp_path.touch(mode=0o600)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o666 & ~_umask())  # give a normal file's mode
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


# --------------------------------------------------------------------------- file sets


def _read_json(path: Path) -> dict | None:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def _move_in(src: Path, dest: Path, trash: Path) -> None:
    """Rename ``src`` over ``dest``; a directory ``dest`` goes to ``trash`` first."""
    if dest.is_dir() and not dest.is_symlink():
        os.replace(dest, trash)
    os.replace(src, dest)


def _roll_forward(folder: Path, journal: dict) -> None:
    """Finish a commit: idempotent, so a commit killed again is finished the next time."""
    staging = folder / str(journal.get("staging", ""))
    for name in journal.get("remove", []):
        _remove(folder / name)
    for i, name in enumerate(journal.get("move", [])):
        src = staging / name
        if src.exists():
            _move_in(src, folder / name, staging / f".replaced-{i}")
    (folder / JOURNAL).unlink(missing_ok=True)
    if staging != folder and staging.name.startswith(STAGING):
        shutil.rmtree(staging, ignore_errors=True)


def finish_commit(folder: str | Path) -> bool:
    """Roll an interrupted commit of ``folder`` forward (readers call this); True if one was.

    A commit whose writer still runs is left to it.
    """
    folder = Path(folder)
    journal = _read_json(folder / JOURNAL)
    if journal is None or _alive(int(journal.get("pid", -1))):
        return False
    log.warning("%s: finishing the interrupted commit of a run's outputs", folder)
    _roll_forward(folder, journal)
    return True


def recover_folder(folder: str | Path) -> None:
    """Bring ``folder`` back to one complete set of outputs after a killed run.

    An interrupted commit is rolled forward; staging folders without a journal, and
    temporary files of killed writers, are removed.
    """
    folder = Path(folder)
    if not folder.is_dir():
        return
    finish_commit(folder)
    for p in folder.glob(STAGING + "*"):
        pid = p.name[len(STAGING) :]
        if pid.isdigit() and not _alive(int(pid)):
            log.warning("removing %s: the partial outputs of an interrupted run", p)
            shutil.rmtree(p, ignore_errors=True)
    clean_stale_parts(folder)


def _commit(folder: Path, staging: Path) -> list[str]:
    new = sorted(p.name for p in staging.iterdir() if not p.name.startswith("."))
    old = (_read_json(folder / MANIFEST) or {}).get("outputs", [])
    stale = sorted(n for n in old if isinstance(n, str) and "/" not in n and n not in new)
    (staging / MANIFEST).write_text(json.dumps({"outputs": new}, indent=1), encoding="utf-8")
    journal = {"pid": os.getpid(), "staging": staging.name, "move": new + [MANIFEST]}
    journal["remove"] = [n for n in stale if not n.startswith(".")]
    with atomic_path(folder / JOURNAL) as tmp:
        tmp.write_text(json.dumps(journal, indent=1), encoding="utf-8")
    _roll_forward(folder, journal)
    return new


@contextlib.contextmanager
def staged_folder(folder: str | Path) -> Iterator[Path]:
    """Yield a staging folder inside ``folder``; its files replace the previous set as a unit.

    Every output of the set is written into the staging folder. On success the set is
    committed through a journal (see the module docstring); on an exception the staging
    folder is removed and ``folder`` keeps its previous set. The previous set's files that
    the new set does not have (listed in ``folder/.rmpl-outputs.json``) are removed.

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> with staged_folder(d) as stage:
    ...     _ = (stage / "a.txt").write_text("new")
    >>> sorted(p.name for p in d.iterdir())
    ['.rmpl-outputs.json', 'a.txt']
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, None, "an output folder", "a regular file")
    folder.mkdir(parents=True, exist_ok=True)
    recover_folder(folder)
    staging = folder / f"{STAGING}{os.getpid()}"
    _remove(staging)
    staging.mkdir()
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    _commit(folder, staging)
