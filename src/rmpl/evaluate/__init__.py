"""Evaluation: benchmark protocols, synthetic experiments, held-out-view errors, tables, plots.

``harness`` scores methods on a :class:`rmpl.data.base.MultiViewDataset`; ``synthetic`` builds
scenes from motion capture or MHP renders; ``heldout`` predicts each camera from the others
on recordings with no ground truth; ``plots`` draws the sweeps.
"""
