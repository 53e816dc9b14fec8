"""The robot files written without PyYAML's representer or ElementTree are their text, and the
DH tables' forward kinematics is the product of its link matrices to the last bit."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from zrp_ga import robots
from zrp_ga.io import robot_files, urdf
from zrp_ga.model import dh, so3
from zrp_ga.model.robot import ZRPRobot

NAMES = ["a", "joint_1", "x-y", "a.b", "yes", "1.5", "on", "null", "b c", "caf\u00e9", "[x]", "#c", "- d",
         "very_long_name_" * 6]  # fmt: skip


def _floats(rng, n):
    return (rng.normal(size=n) * 10.0 ** rng.integers(-20, 20, n)).tolist() if rng.random() < 0.5 else rng.normal(size=n).tolist()


def _document(rng, depth=0):
    """A mapping of the shapes robot files hold: names, floats, lists of floats, lists of them, mappings."""
    doc = {}
    for k in range(rng.integers(1, 6)):
        key = str(rng.choice(NAMES[:4])) + str(k) if rng.random() < 0.9 else str(rng.choice(NAMES))
        kind = rng.integers(0, 6 if depth < 2 else 4)
        if kind == 0:
            doc[key] = _floats(rng, 1)[0]
        elif kind == 1:
            doc[key] = str(rng.choice(NAMES[:4])) if rng.random() < 0.8 else str(rng.choice(NAMES))
        elif kind == 2:
            doc[key] = _floats(rng, rng.integers(1, 9))
        elif kind == 3:
            doc[key] = [_floats(rng, rng.integers(1, 6)) for _ in range(rng.integers(1, 5))]
        elif kind == 4:
            doc[key] = {str(rng.choice(NAMES[:4])): _floats(rng, 1)[0] for _ in range(rng.integers(1, 6))}
        else:
            doc[key] = _document(rng, depth + 1)
    return doc


def test_the_yaml_of_the_robot_files_is_what_pyyaml_writes():
    """Wrapped flow sequences (past 80 characters), nested mappings, names YAML would quote."""
    rng = np.random.default_rng(4)
    wrapped = 0
    for _ in range(3000):
        doc = _document(rng)
        text = robot_files._yaml_text(doc)
        assert text == yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
        wrapped += any(line.startswith(" ") and line.lstrip()[:1] not in "-" and ": " not in line for line in text.splitlines())
    assert wrapped > 100  # the wrapping was exercised
    arm = robots.get("ur10")
    assert robot_files._yaml_text(arm.to_dict()) == arm.to_yaml()


def _element_tree_urdf(robot: ZRPRobot, base, tool) -> str:
    """The new URDF of the exact mapping (zrp_ga.io.urdf's docstring) built with ElementTree."""
    names = robot.joint_names or tuple(f"joint_{i + 1}" for i in range(robot.n))
    root = ET.Element("robot", name=robot.name)

    def joint(name, kind, parent, child, T):
        element = ET.SubElement(root, "joint", name=name, type=kind)
        ET.SubElement(element, "parent", link=parent)
        ET.SubElement(element, "child", link=child)
        numbers = lambda v: " ".join(repr(float(x)) for x in np.asarray(v).ravel())
        ET.SubElement(element, "origin", xyz=numbers(T[:3, 3]), rpy=numbers(so3.rpy(T[:3, :3])))
        return element, numbers

    if base is not None:
        ET.SubElement(root, "link", name="world")
        joint("base_joint", "fixed", "world", "base_link", base)
    ET.SubElement(root, "link", name="base_link")
    parent = "base_link"
    for i in range(robot.n):
        ET.SubElement(root, "link", name=f"link_{i + 1}")
        T = np.eye(4)
        T[:3, 3] = robot.b0[i]
        element, numbers = joint(names[i], "revolute" if robot.joint_types[i] == "R" else "prismatic", parent,
                                 f"link_{i + 1}", T)  # fmt: skip
        ET.SubElement(element, "axis", xyz=numbers(robot.u0[i]))
        lower, upper = robot.joint_limits[i]
        ET.SubElement(element, "limit", lower=repr(float(lower)), upper=repr(float(upper)), effort="0", velocity="0")
        parent = f"link_{i + 1}"
    ET.SubElement(root, "link", name="hand")
    hand = np.eye(4)
    hand[:3, :3], hand[:3, 3] = robot.R_h0, robot.b0[-1]
    joint("hand_joint", "fixed", parent, "hand", hand)
    if tool is not None:
        ET.SubElement(root, "link", name="tool")
        joint("tool_joint", "fixed", "hand", "tool", tool)
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


@pytest.mark.parametrize("name", ["stanford", "puma560"])
@pytest.mark.parametrize("odd", [False, True])
def test_a_new_urdf_is_what_element_tree_writes(name, odd):
    rng = np.random.default_rng(2)
    arm = robots.get(name)
    arm = arm.replace(u0=arm.u0 + rng.normal(0, 1e-3, arm.u0.shape), normalize=True, source=None)
    if odd:
        arm = arm.replace(name='a&b <c> "q" \'r\'\tx\ny', joint_names=("j&", "<j>", '"j"', "caf\u00e9", "j 5", "j6"))
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = so3.rodrigues(0.3, np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)), [0.1, -0.2, 0.3]
    for base, tool in ((None, None), (pose, None), (None, pose), (pose, pose)):
        assert urdf.to_urdf(arm, base=base, tool=tool) == _element_tree_urdf(arm, base, tool)


def _factor(axis: str, value: float) -> np.ndarray:
    """A rotation (rx, ry, rz) or translation (tx, tz) 4x4 matrix."""
    T = np.eye(4)
    if axis[0] == "t":
        T["xyz".index(axis[1]), 3] = value
        return T
    j, k = {"rx": (1, 2), "ry": (2, 0), "rz": (0, 1)}[axis]
    T[j, j] = T[k, k] = np.cos(value)
    T[k, j], T[j, k] = np.sin(value), -np.sin(value)
    return T


@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_the_forward_kinematics_of_a_table_is_the_product_of_its_link_matrices_to_the_last_bit(convention):
    """What to_dh's mismatch rests on: the same products in the same order as the chain of the
    convention's factor matrices (module docstring of zrp_ga.model.dh), Hayati rows and prismatic joints too."""
    rng = np.random.default_rng(6)
    for trial in range(40):
        n = int(rng.integers(1, 7))
        types = "".join(rng.choice(["R", "P"], n))
        a, alpha, d, theta = (rng.normal(size=n) for _ in range(4))
        alpha[rng.random(n) < 0.3] = np.pi / 2
        beta = np.where(rng.random(n) < 0.3, rng.normal(0, 1e-3, n), 0.0)
        base, tool = np.eye(4), np.eye(4)
        base[:3, :3], base[:3, 3] = so3.rodrigues(1.0, (lambda u: u / np.linalg.norm(u))(rng.normal(size=3))), rng.normal(size=3)
        tool[:3, 3] = rng.normal(size=3)
        table = dh.DHTable(convention, a, alpha, d, theta, types, base=base, tool=tool, beta=beta)
        q = rng.normal(size=(7, n))
        for k in range(len(q)):
            T = base
            for i in range(n):
                th, di = (theta[i] + q[k, i], d[i] + 0.0) if types[i] == "R" else (theta[i] + 0.0, d[i] + q[k, i])
                tilt = _factor("ry", beta[i]) if beta[i] else np.eye(4)
                if convention == "dh":
                    link = _factor("rz", th) @ _factor("tz", di) @ _factor("tx", a[i]) @ _factor("rx", alpha[i]) @ tilt
                else:
                    link = _factor("rx", alpha[i]) @ _factor("tx", a[i]) @ tilt @ _factor("rz", th) @ _factor("tz", di)
                T = T @ link
            assert np.array_equal(table.forward(q)[k], T @ tool)
            assert np.array_equal(table.forward(q[k]), T @ tool)


def test_both_tables_at_once_are_to_dhs():
    rng = np.random.default_rng(3)
    for name in robots.names():
        arm = robots.get(name)
        arm = arm.replace(u0=arm.u0 + rng.normal(0, 1e-3, arm.u0.shape), normalize=True, source=None)
        both = dh.tables(arm)
        for convention in dh.CONVENTIONS:
            table, mismatch = dh.to_dh(arm, convention)
            assert both[convention][1] == mismatch
            for field in ("a", "alpha", "d", "theta", "beta", "base", "tool"):
                assert np.array_equal(getattr(both[convention][0], field), getattr(table, field))


def _shortest(v: float) -> float:
    """Of v + k ulp (k = -8..8), the one whose repr is shortest; ties to the smaller |k|, then k."""
    ulp = math.copysign(math.ulp(v), v) if v else 5e-324
    candidates = [v + k * ulp for k in range(-8, 9)]
    return min(zip(candidates, range(-8, 9)), key=lambda c: (len(repr(c[0])), abs(c[1]), c[1]))[0] + 0.0


def test_short_numbers_near_short_decimals_and_powers_of_ten():
    """The numbers of 13 digits or fewer taken as they are, their neighbours searched, the
    numbers searched before remembered: all as the definition says."""
    rng = np.random.default_rng(9)
    values = []
    for k in range(-95, 14, 3):
        for x in rng.normal(size=6) * 10.0**k:
            for p in (1, 4, 12, 13, 14, 15):
                r = float(f"{x:.{p}g}")
                values += [r, np.nextafter(r, np.inf), np.nextafter(r, -np.inf), r + 5 * math.ulp(r)]
        values += [10.0**k, np.nextafter(10.0**k, 0), -np.nextafter(10.0**k, np.inf)]
    values += [2.0**k for k in range(-60, 60, 7)] + [0.0, -0.0]
    expected = [_shortest(v) for v in values]
    for _ in range(2):  # the second time from memory
        got = robot_files._short(values)
        assert got == expected
        assert [math.copysign(1, g) for g in got] == [math.copysign(1, e) for e in expected]
