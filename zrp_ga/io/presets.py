"""Preset arms: ``get(name)`` returns a :class:`~zrp_ga.model.robot.ZRPRobot`.

The presets are DH table files shipped in ``zrp_ga/data/robots`` (format:
:mod:`zrp_ga.io.robot_files`; :func:`path` gives the file, a template for your own arm):

- ``puma560``: Corke's standard-DH PUMA 560 (Robotics Toolbox, ``Puma560``), with the
  shoulder height d1 = 0.67183 m so that the world frame is at the floor; the end-effector
  point is the wrist centre (docs/model.md, section 1).
- ``ur10``: Universal Robots' published standard-DH values for the UR10 (end point on the
  flange).
- ``stanford``: the Stanford arm (Corke's ``Stanford``), joint 3 prismatic.
"""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path

from zrp_ga.io.robot_files import read_robot
from zrp_ga.model.robot import ZRPRobot

_FILES = resources.files("zrp_ga.data.robots")


def names() -> list[str]:
    """Names of the preset robots."""
    return sorted(f.name.removesuffix(".yaml") for f in _FILES.iterdir() if f.name.endswith(".yaml"))


def path(name: str) -> Path:
    """The DH table file of the preset ``name``."""
    if name not in names():
        raise ValueError(f"unknown robot {name!r}; known robots: {', '.join(names())}")
    return Path(str(_FILES / f"{name}.yaml"))


@functools.cache
def get(name: str) -> ZRPRobot:
    """The preset robot called ``name`` (read once; robots are immutable).

    >>> get("puma560")
    ZRPRobot(name='puma560', n=6, joint_types='RRRRRR')
    """
    return read_robot(path(name))


def load(name: str | None = None, file: str | None = None, base_link: str | None = None, tip_link: str | None = None) -> ZRPRobot:
    """The robot of the config's ``robot`` group: the robot file ``file`` if given (a DH or
    modified-DH table, a ZRP YAML or a URDF, whose chain runs from ``base_link`` to
    ``tip_link``; ``pkg:REL`` for a file shipped in zrp_ga/data), else the preset ``name``."""
    if file:
        from zrp_ga.data import resolve

        return read_robot(resolve(file), base_link=base_link, tip_link=tip_link)
    if not name:
        raise ValueError("robot: give a preset name (robot.name) or a robot file (robot.file)")
    return get(name)
