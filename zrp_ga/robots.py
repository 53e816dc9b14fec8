"""Preset arms and the arm's description, as other code calls them (the public contract):
``zrp_ga.robots.get("puma560")`` returns a :class:`ZRPRobot`; ``names()`` lists the presets,
``path(name)`` gives a preset's file (a template for your own arm), ``load(name=, file=)``
reads a preset or a robot file. The functions live in :mod:`zrp_ga.io.presets`, the class in
:mod:`zrp_ga.model.robot`; the package's own code imports them from there.

>>> from zrp_ga import robots
>>> robots.get("puma560").n
6
"""

from zrp_ga.io.presets import get, load, names, path
from zrp_ga.model.robot import ZRPRobot

__all__ = ["ZRPRobot", "get", "load", "names", "path"]
