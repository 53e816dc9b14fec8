"""Preset arms: ``get(name)`` returns a :class:`~zrp_ga.robot.ZRPRobot`.

- ``puma560``: Corke's standard-DH PUMA 560 (Robotics Toolbox, ``Puma560``), with the
  shoulder height d1 = 0.67183 m so that the world frame is at the floor; the end-effector
  point is the wrist centre (DESIGN.md section 1).
- ``ur10``: Universal Robots' published standard-DH values for the UR10 (end point on the
  flange).
- ``stanford``: the Stanford arm (Corke's ``Stanford``), joint 3 prismatic.
"""

from __future__ import annotations

import numpy as np

from zrp_ga.robot import ZRPRobot

_DEG = np.pi / 180.0

# name -> (table kind, d, a, alpha, offset, joint types); lengths m, angles rad.
_TABLES = {
    "puma560": dict(
        d=[0.67183, 0.0, 0.15005, 0.4318, 0.0, 0.0],
        a=[0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0],
        alpha=np.array([90, 0, -90, 90, -90, 0]) * _DEG,
        joint_types="RRRRRR",
    ),
    "ur10": dict(
        d=[0.1273, 0.0, 0.0, 0.163941, 0.1157, 0.0922],
        a=[0.0, -0.612, -0.5723, 0.0, 0.0, 0.0],
        alpha=np.array([90, 0, 0, 90, -90, 0]) * _DEG,
        joint_types="RRRRRR",
    ),
    "stanford": dict(
        d=[0.412, 0.154, 0.0, 0.0, 0.0, 0.263],
        a=[0.0, 0.0, 0.0203, 0.0, 0.0, 0.0],
        alpha=np.array([-90, 90, 0, -90, 90, 0]) * _DEG,
        offset=[0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0],
        joint_types="RRPRRR",
    ),
}


def names() -> list[str]:
    """Names of the preset robots."""
    return sorted(_TABLES)


def dh_table(name: str) -> dict:
    """The standard-DH table of a preset (keys d, a, alpha, offset, joint_types)."""
    _check(name)
    table = dict(_TABLES[name])
    table.setdefault("offset", [0.0] * len(table["d"]))
    return table


def get(name: str) -> ZRPRobot:
    """The preset robot called ``name``.

    >>> get("puma560")
    ZRPRobot(name='puma560', n=6, joint_types='RRRRRR')
    """
    return ZRPRobot.from_dh(**dh_table(name), name=name)


def _check(name: str) -> None:
    if name not in _TABLES:
        raise ValueError(f"unknown robot {name!r}; known robots: {', '.join(names())}")


def load(name: str | None = None, file: str | None = None) -> ZRPRobot:
    """The robot of the config's ``robot`` group: the file ``file`` if given, else the preset ``name``."""
    from pathlib import Path

    if file:
        return ZRPRobot.from_yaml(Path(file).expanduser())
    if not name:
        raise ValueError("robot: give a preset name (robot.name) or a file (robot.file)")
    return get(name)
