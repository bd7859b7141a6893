"""Tables: Markdown cells, CSV columns, the sweep table and writing a report."""

import csv
import math

from rmpl.evaluate.tables import Report, markdown_table, save_report, sweep_table, write_csv


def _rows():
    out = []
    for method, base in (("a", 50.0), ("b", 40.0)):
        for p in (0.0, 0.5):
            out.append(
                {"views": "2 views", "method": method, "mpjpe": base + 100 * p, "dropout": p}
                | {"calib_noise": "none", "coverage": math.nan}
            )
    return out


def test_markdown_table_cells():
    text = markdown_table(_rows()[:1], ["views", "method", "mpjpe", "coverage", "pck"], 100)
    lines = text.splitlines()
    assert lines[0] == "| views | method | MPJPE (mm) | coverage (%) | PCK@100mm (%) |"
    assert lines[1] == "|---|---|---:|---:|---:|"
    assert lines[2] == "| 2 views | a | 50.0 | — | — |"  # NaN and absent: an em dash


def test_sweep_table_one_column_per_condition():
    lines = sweep_table(_rows(), (0.0, 0.5), None).splitlines()
    assert lines[0] == "| views | method | p=0 | p=0.5 |"
    assert lines[2:] == ["| 2 views | a | 50.0 | 100.0 |", "| 2 views | b | 40.0 | 90.0 |"]


def test_csv_and_report(tmp_path):
    rows = [{"x": 1.0, "y": "s"}, {"x": 2.5, "z": 3}]
    write_csv(tmp_path / "t.csv", rows)
    with open(tmp_path / "t.csv", newline="") as f:
        back = list(csv.DictReader(f))
    assert list(back[0]) == ["x", "y", "z"]  # union of keys, first-seen order
    assert back[0]["x"] == "1.0000" and back[1]["z"] == "3"
    drawn = []
    report = Report("# t", {"results.md": "# t", "results.csv": rows}, drawn.append)
    save_report(tmp_path / "out", report, plots=False)
    assert (tmp_path / "out" / "results.md").read_text() == "# t" and drawn == []
    save_report(tmp_path / "out", report)
    assert drawn == [tmp_path / "out"]
