"""Evaluation: methods compared on identical 2D input, scored, tabulated and plotted.

The modules, in the order the data flows through them:

- ``methods``: the compared methods, ``fn(keypoints, scores, rig) -> points``;
- ``evalset``: a real dataset with 3D ground truth and the 2D input chosen for it;
- ``harness``: every method on every view subset and condition (dropout, calibration
  noise) of an evaluation set, or finished results matched to the ground truth;
- ``synthetic`` / ``heldout``: the same for simulated scenes (random cameras, MHP renders,
  the two-camera sphere) and for recordings without ground truth (held-out views);
- ``scoring``: MPJPE, KP*, PA-MPJPE, PCK, coverage, PCP;
- ``tables``: rows, Markdown, CSV, and the :class:`~rmpl.evaluate.tables.Report` of a run;
- ``plots``: the PNG figures;
- ``options``, ``protocols``, ``experiments``: the runs of ``rmpl evaluate`` (real
  datasets and recordings; synthetic experiments), each ending in a report.
"""
