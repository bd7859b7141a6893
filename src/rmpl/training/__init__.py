"""Training the lifter on synthetic 2D-3D pairs.

The pairs come from :mod:`rmpl.data.synthetic` and :mod:`rmpl.data.mhp`; ``loop`` holds the
configuration, the optimisation loop and the checkpoints.
"""
