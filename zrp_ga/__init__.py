"""zrp_ga: genetic-algorithm calibration of serial robot kinematics on the Zero Reference
Position model. See the README for the layout of the package; :func:`calibrate` is the entry
point for scripts and notebooks."""

from __future__ import annotations

from typing import Any


def __getattr__(name: str) -> Any:
    """``__version__``, ``calibrate``, ``load``, ``simulate``, ``Calibration``, ``compensate`` and ``ZrpGaWarning`` on first use: importing the package stays cheap."""
    if name == "__version__":
        from importlib import metadata

        try:
            return metadata.version("zrp_ga")
        except metadata.PackageNotFoundError:  # a source tree that is not installed
            return "0+unknown"
    if name in ("calibrate", "load", "simulate", "Calibration"):  # zrp_ga.api: a calibration made, kept, rehearsed
        from zrp_ga import api

        return getattr(api, name)
    if name == "ZrpGaWarning":  # the class of every warning zrp_ga gives inside the API
        from zrp_ga.core.errors import ZrpGaWarning

        return ZrpGaWarning
    if name == "compensate":  # zrp_ga.compensation: a calibration turned into a corrected program
        return __import__("zrp_ga.compensation.compensate", fromlist=["compensate"]).compensate
    raise AttributeError(f"module 'zrp_ga' has no attribute {name!r}")


__all__ = ["Calibration", "ZrpGaWarning", "calibrate", "compensate", "load", "simulate"]
