"""The RMPL network: config, module and building blocks."""

from rmpl.model.lifter import PRESETS, RMPL, RMPLConfig

__all__ = ["PRESETS", "RMPL", "RMPLConfig"]
