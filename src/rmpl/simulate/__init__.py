"""rmpl simulate: a ground-truth twin of a capture."""
