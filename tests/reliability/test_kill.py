"""kill -9 faults: what a killed write leaves, and that the next run cleans it up."""

from __future__ import annotations

import os

import numpy as np
import pytest

from rmpl.io.atomic import atomic_path, clean_stale_parts
from tests.reliability._faults import run_killed


def hidden(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.mark.parametrize("suffix", [".json", ".npz", ".pt"])
def test_killed_write_leaves_a_part_file_the_next_write_removes(tmp_path, suffix):
    (tmp_path / f"out{suffix}").write_text("old")
    run_killed(
        f"""
        from rmpl.io.atomic import atomic_path
        with atomic_path("out{suffix}") as tmp:
            tmp.write_bytes(b"x" * 100000)
            die()
        """,
        tmp_path,
    )
    assert (tmp_path / f"out{suffix}").read_text() == "old"  # the old file is intact
    assert len(hidden(tmp_path)) == 1  # the killed writer's temporary file
    with atomic_path(tmp_path / "other.txt") as tmp:  # any later write into the folder
        tmp.write_text("new")
    assert hidden(tmp_path) == []


def test_part_file_of_a_running_writer_is_kept(tmp_path):
    with atomic_path(tmp_path / "a.json") as tmp:
        tmp.write_text("{}")
        assert clean_stale_parts(tmp_path) == 0
        assert tmp.exists()
    assert (tmp_path / "a.json").read_text() == "{}"


def test_part_files_of_the_old_naming_are_removed(tmp_path):
    old = tmp_path / ".out.json.k2j_9xa0.part.json"  # tempfile.mkstemp's, before 0.1.1
    old.write_text("partial")
    assert clean_stale_parts(tmp_path) == 1
    assert not old.exists()


def test_killed_checkpoint_write_is_cleaned_by_the_next(tmp_path):
    run_killed(
        """
        import torch
        from rmpl.io.atomic import atomic_path
        with atomic_path("state.pt") as tmp:
            die()
        """,
        tmp_path,
    )
    assert len(hidden(tmp_path)) == 1
    with atomic_path(tmp_path / "state.pt") as tmp:
        np.save(open(tmp, "wb"), np.zeros(3))
    assert hidden(tmp_path) == [] and os.path.getsize(tmp_path / "state.pt") > 0
