"""Writing a calibration that spans several files (EasyMocap's pair) as one unit."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from pathlib import Path

from rmpl.errors import InputError
from rmpl.io.atomic import PART_TAG, atomic_path


def write_all(files: dict[Path, str]) -> None:
    """Write every file of ``files`` (path -> text) or none of them.

    Each text is first written whole to a temporary file beside its target; only then are
    they moved into place. If a move fails, the files already moved are put back as they
    were, so the previous set stays complete.

    Raises:
        InputError: a target is an existing folder (nothing is written).
    """
    for dst in files:
        if dst.is_dir():
            raise InputError(dst, None, "a file path to write", "an existing folder")
    backups = {dst: _backup(dst) for dst in files if dst.is_file()}
    try:
        with contextlib.ExitStack() as stack:
            tmps = {dst: stack.enter_context(atomic_path(dst)) for dst in files}
            for dst, text in files.items():
                tmps[dst].write_text(text, encoding="utf-8")
    except BaseException:
        _restore(files, backups)
        raise
    finally:
        for backup in backups.values():
            backup.unlink(missing_ok=True)


def _backup(path: Path) -> Path:
    """A copy of ``path`` under a temporary name that later writes clean up if we are killed."""
    token = secrets.token_hex(4)
    backup = path.parent / f".{path.name}.{os.getpid()}-{token}{PART_TAG}{path.suffix}"
    shutil.copy2(path, backup)
    return backup


def _restore(files: dict[Path, str], backups: dict[Path, Path]) -> None:
    """Put back the previous version of every target; remove targets that had none."""
    for dst in files:
        if dst in backups:
            os.replace(backups[dst], dst)
        else:
            dst.unlink(missing_ok=True)
