"""An independent URDF forward-kinematics walk (xml.etree and scipy), written for the tests only."""

import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation


def _numbers(element, attr, default):
    text = None if element is None else element.get(attr)
    return np.array(default if text is None else [float(v) for v in text.split()])


def urdf_fk(path, q, frm, to):
    """Pose (4, 4) of link ``to`` in link ``frm`` (an ancestor) of the URDF at ``path``; ``q``:
    joint name -> value (rad or m; joints not given are at 0). Each joint: origin
    (``Rz(yaw) Ry(pitch) Rx(roll)``, translation xyz) times its motion about or along its axis."""
    root = ET.parse(path).getroot()
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
    T, link = np.eye(4), to
    while link != frm:
        joint = by_child[link]
        origin, axis = joint.find("origin"), joint.find("axis")
        A = np.eye(4)
        A[:3, :3] = Rotation.from_euler("xyz", _numbers(origin, "rpy", [0, 0, 0])).as_matrix()
        A[:3, 3] = _numbers(origin, "xyz", [0, 0, 0])
        u = _numbers(axis, "xyz", [1, 0, 0])
        u = u / np.linalg.norm(u)
        motion, value = np.eye(4), q.get(joint.get("name"), 0.0)
        if joint.get("type") in ("revolute", "continuous"):
            motion[:3, :3] = Rotation.from_rotvec(u * value).as_matrix()
        elif joint.get("type") == "prismatic":
            motion[:3, 3] = u * value
        T = A @ motion @ T
        link = joint.find("parent").get("link")
    return T
