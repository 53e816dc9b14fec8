"""URDF in and out for ZRP arms (docs/model.md, section 5).

Reading (:func:`read_urdf`) parses with yourdfpy; lxml (yourdfpy's XML library) only checks
that the file is well-formed XML and gives the line of each joint for error messages. The serial
chain from ``base_link`` to ``tip_link`` (defaults: the root link and its single leaf) is walked
at q = 0: fixed joints fold into their neighbours; each revolute, continuous or prismatic joint
gives a ZRP axis, the joint frame's rotation times the URDF axis, through the joint frame's
origin; the tip link's frame gives ``R_h0`` and the end point. Joint names and limits are kept
(continuous joints, and joints without lower and upper limits, get
:data:`~zrp_ga.robot.DEFAULT_LIMITS`). Floating, planar and mimic joints in the chain are refused.

Writing (:func:`to_urdf`) uses :mod:`xml.etree.ElementTree`: writing is a few elements. The
mapping is exact, with link frames world-aligned at q = 0: joint i has ``origin xyz = b0_i``
(from the previous joint's point), ``rpy = 0``, ``axis = u0_i``; the fixed ``hand_joint``
carries ``b0_{n+1}`` and ``rpy(R_h0)``. Links are ``base_link``, ``link_1`` .. ``link_n`` and
``hand``.

Errors are ValueErrors of one line naming the file and the line or the joint.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from zrp_ga import so3
from zrp_ga.robot import DEFAULT_LIMITS, MAX_ANGLE_RAD, MAX_LENGTH_M, ZRPRobot

Array = NDArray[np.float64]
_MOVABLE = {"revolute": "R", "continuous": "R", "prismatic": "P"}
_FIXED_JOINTS = ("base_joint", "hand_joint", "tool_joint")  # names the written URDF uses


def read_urdf(
    path: str | Path, text: str | None = None, base_link: str | None = None, tip_link: str | None = None
) -> ZRPRobot:
    """The ZRP arm of the chain ``base_link`` .. ``tip_link`` of a URDF (module docstring).

    ``text``: the file's text if already read. Prefer :func:`zrp_ga.robot_files.read_robot`,
    which also checks the path.
    """
    path = Path(path)
    lines = _check_xml(path, path.read_text() if text is None else text)
    model = _load(path)
    chain, base, tip = _chain(path, model.robot, lines, base_link, tip_link)
    return _zrp(path, model.robot.name, chain, lines, base, tip)


def _check_xml(path: Path, text: str) -> dict[str, int]:
    """Well-formed XML with a <robot> root and complete <joint> elements; joint name -> line."""
    from lxml import etree

    try:
        root = etree.fromstring(text.encode("utf-8"))
    except etree.XMLSyntaxError as exc:
        line, column = exc.position
        raise ValueError(_one_line(f"{path}, line {line}, column {column}: malformed XML: {exc.msg}")) from None
    if root.tag != "robot" or not root.get("name"):
        got = f"got <{root.tag}>"
        raise ValueError(f"{path}, line {root.sourceline}: not a URDF: expected <robot name=...> as the root, {got}")
    lines = {}
    for joint in root.findall("joint"):
        name = joint.get("name")
        where = f"{path}, line {joint.sourceline}: joint {name!r}"
        if not name:
            raise ValueError(f"{path}, line {joint.sourceline}: a <joint> without a name")
        if name in lines:
            raise ValueError(f"{where}: name already used by the joint on line {lines[name]}")
        for tag in ("parent", "child"):
            if joint.find(tag) is None or not joint.find(tag).get("link"):
                raise ValueError(f"{where}: missing <{tag} link=...>")
        if not joint.get("type"):
            raise ValueError(f"{where}: missing type")
        _check_numbers(where, joint)
        lines[name] = joint.sourceline
    return lines


def _check_numbers(where: str, joint) -> None:
    """The joint's origin, axis and limit attributes: the right count of finite, sane numbers."""
    limit_bound = MAX_LENGTH_M if joint.get("type") == "prismatic" else MAX_ANGLE_RAD
    for tag, attr, count, bound in (
        ("origin", "xyz", 3, MAX_LENGTH_M), ("origin", "rpy", 3, MAX_ANGLE_RAD), ("axis", "xyz", 3, MAX_LENGTH_M),
        ("limit", "lower", 1, limit_bound), ("limit", "upper", 1, limit_bound),
    ):
        element = joint.find(tag)
        text = None if element is None else element.get(attr)
        if text is None:
            continue
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            raise ValueError(f"{where}: <{tag} {attr}={text!r}>: not numbers") from None
        if len(values) != count:
            raise ValueError(f"{where}: <{tag} {attr}={text!r}>: expected {count} number(s), got {len(values)}")
        if not np.all(np.isfinite(values)) or np.max(np.abs(values)) > bound:
            raise ValueError(f"{where}: <{tag} {attr}={text!r}>: not finite or absurd (beyond {bound:g} m or rad)")


def _load(path: Path):
    """The yourdfpy model, without meshes or scene graph."""
    import yourdfpy  # deferred: it imports trimesh, about a second

    try:
        return yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
    except Exception as exc:  # yourdfpy's parser lets KeyError, AttributeError, ValueError, ... through
        raise ValueError(_one_line(f"{path}: not a URDF yourdfpy can read ({type(exc).__name__}: {exc})")) from None


def _chain(
    path: Path, robot, lines: dict[str, int], base_link: str | None, tip_link: str | None
) -> tuple[list, str, str]:
    """The joints from ``base_link`` to ``tip_link`` (defaults: the single root and leaf), base first."""
    links = [link.name for link in robot.links]
    by_child, children = _tree(path, robot, lines)
    roots = [k for k in links if k not in by_child]
    base = base_link if base_link is not None else _only(path, roots, "root links", "base_link")
    _known(path, base, links, "base_link")
    below, todo = [], [base]
    while todo and len(below) <= len(links):
        below.append(todo.pop())
        todo += children[below[-1]]
    leaves = [k for k in below if not children[k]]
    tip = tip_link if tip_link is not None else _only(path, leaves, f"leaf links below {base!r}", "tip_link")
    _known(path, tip, links, "tip_link")
    chain, link = [], tip
    while link != base:
        if link not in by_child or len(chain) > len(robot.joints):
            raise ValueError(f"{path}: tip_link {tip!r} is not below base_link {base!r}")
        chain.append(by_child[link])
        link = chain[-1].parent
    return chain[::-1], base, tip


def _tree(path: Path, robot, lines: dict[str, int]) -> tuple[dict, dict[str, list[str]]]:
    """child link -> its joint, and link -> child links; joints must name known links, a link one parent."""
    by_child, children = {}, {link.name: [] for link in robot.links}
    for joint in robot.joints:
        for link in (joint.parent, joint.child):
            if link not in children:
                raise _joint_error(path, lines, joint.name, f"unknown link {link!r}")
        if joint.child in by_child:
            other = by_child[joint.child].name
            raise _joint_error(path, lines, joint.name, f"link {joint.child!r} is already the child of {other!r}")
        by_child[joint.child] = joint
        children[joint.parent].append(joint.child)
    return by_child, children


def _only(path: Path, candidates: list[str], what: str, option: str) -> str:
    if len(candidates) == 1:
        return candidates[0]
    if not candidates:
        raise ValueError(f"{path}: no {what}")
    raise ValueError(f"{path}: {len(candidates)} {what} ({', '.join(candidates)}); choose one with {option}")


def _known(path: Path, link: str, links: list[str], option: str) -> None:
    if link not in links:
        raise ValueError(f"{path}: {option} {link!r} is not a link of the file (links: {', '.join(links)})")


def _zrp(path: Path, name: str, chain: list, lines: dict[str, int], base: str, tip: str) -> ZRPRobot:
    """Walk the chain at q = 0 (module docstring)."""
    T = np.eye(4)
    points, axes, types, names, limits = [], [], [], [], []
    for joint in chain:
        T = T @ (np.eye(4) if joint.origin is None else joint.origin)
        if joint.type == "fixed":
            continue
        if joint.type not in _MOVABLE:
            kinds = "only revolute, continuous, prismatic and fixed joints can be read"
            raise _joint_error(path, lines, joint.name, f"a {joint.type} joint; {kinds}")
        if joint.mimic is not None:
            raise _joint_error(path, lines, joint.name, f"mimics {joint.mimic.joint!r}; mimic joints cannot be read")
        length = np.linalg.norm(joint.axis)
        if length < 1e-12:
            raise _joint_error(path, lines, joint.name, "axis of length zero")
        points.append(T[:3, 3].copy())
        axes.append(T[:3, :3] @ joint.axis / length)
        types.append(_MOVABLE[joint.type])
        names.append(joint.name)
        limits.append(_limits(path, lines, joint))
    if not axes:
        raise ValueError(f"{path}: no movable joint between base_link {base!r} and tip_link {tip!r}")
    b0 = np.diff(np.vstack([np.zeros(3), *points, T[:3, 3]]), axis=0)
    try:
        return ZRPRobot(
            u0=axes, b0=b0, R_h0=T[:3, :3], joint_types="".join(types), name=name, joint_names=names,
            limits=limits, normalize=True,
        )
    except ValueError as exc:  # not expected after the checks above; named all the same
        raise ValueError(_one_line(f"{path}: {exc}")) from None


def _limits(path: Path, lines: dict[str, int], joint) -> tuple[float, float]:
    """(lower, upper) of a movable joint, defaults where the file gives none (continuous joints)."""
    lower, upper = DEFAULT_LIMITS[_MOVABLE[joint.type]]
    if joint.type != "continuous" and joint.limit is not None:
        lower = lower if joint.limit.lower is None else joint.limit.lower
        upper = upper if joint.limit.upper is None else joint.limit.upper
    if not lower < upper:
        raise _joint_error(path, lines, joint.name, f"limit lower {lower:g} is not below upper {upper:g}")
    return lower, upper


def _joint_error(path: Path, lines: dict[str, int], joint: str, message: str) -> ValueError:
    line = f", line {lines[joint]}" if joint in lines else ""
    return ValueError(_one_line(f"{path}{line}: joint {joint!r}: {message}"))


def _one_line(text: str) -> str:
    return " ".join(text.split())


def to_urdf(
    robot: ZRPRobot, path: str | Path | None = None, base: ArrayLike | None = None, tool: ArrayLike | None = None
) -> str:
    """URDF text of a ZRP arm (the exact mapping of docs/model.md, section 5, module docstring); also written to ``path``.

    ``base`` (4x4): pose of the robot's world frame (link ``base_link``) in an outer frame, added
    as link ``world`` and fixed joint ``base_joint``; ``tool`` (4x4): pose of a tool frame in the
    hand frame, added as link ``tool`` and fixed joint ``tool_joint``. Joint names are the robot's
    (``joint_<i>`` if it has none) and its limits (:attr:`ZRPRobot.joint_limits`) are written;
    effort and velocity limits are unknown here and written as 0.

    >>> from zrp_ga import robots
    >>> "<axis xyz=\\"0.0 0.0 1.0\\" />" in to_urdf(robots.get("puma560"))
    True
    """
    names = robot.joint_names or tuple(f"joint_{i + 1}" for i in range(robot.n))
    clash = sorted(set(names) & set(_FIXED_JOINTS))
    if clash:
        raise ValueError(f"joint names {', '.join(clash)}: reserved for the URDF's fixed joints")
    root = ET.Element("robot", name=robot.name)
    if base is not None:
        ET.SubElement(root, "link", name="world")
        _urdf_joint(root, "base_joint", "fixed", "world", "base_link", check_transform(base, "base"))
    ET.SubElement(root, "link", name="base_link")
    parent = "base_link"
    for i in range(robot.n):
        T = np.eye(4)
        T[:3, 3] = robot.b0[i]
        ET.SubElement(root, "link", name=f"link_{i + 1}")
        kind = "revolute" if robot.joint_types[i] == "R" else "prismatic"
        joint = _urdf_joint(root, names[i], kind, parent, f"link_{i + 1}", T)
        ET.SubElement(joint, "axis", xyz=_numbers(robot.u0[i]))
        lower, upper = robot.joint_limits[i]
        ET.SubElement(joint, "limit", lower=repr(float(lower)), upper=repr(float(upper)), effort="0", velocity="0")
        parent = f"link_{i + 1}"
    hand = np.eye(4)
    hand[:3, :3], hand[:3, 3] = robot.R_h0, robot.b0[-1]
    ET.SubElement(root, "link", name="hand")
    _urdf_joint(root, "hand_joint", "fixed", parent, "hand", hand)
    if tool is not None:
        ET.SubElement(root, "link", name="tool")
        _urdf_joint(root, "tool_joint", "fixed", "hand", "tool", check_transform(tool, "tool"))
    ET.indent(root)
    text = '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    if path is not None:
        Path(path).write_text(text)
    return text


def _urdf_joint(root: ET.Element, name: str, kind: str, parent: str, child: str, T: Array) -> ET.Element:
    joint = ET.SubElement(root, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    ET.SubElement(joint, "origin", xyz=_numbers(T[:3, 3]), rpy=_numbers(so3.rpy(T[:3, :3])))
    return joint


def _numbers(v: ArrayLike) -> str:
    return " ".join(repr(float(x)) for x in np.asarray(v).ravel())  # repr: floats in full


def check_transform(T: ArrayLike, what: str) -> Array:
    """A checked 4x4 rigid transform (rotation orthonormal to 1e-9, last row 0 0 0 1)."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{what}: expected a finite 4x4 transform, got shape {T.shape}")
    R = T[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-9 or np.linalg.det(R) < 0 or np.abs(T[3] - [0, 0, 0, 1]).max() > 0:
        raise ValueError(f"{what}: not a rigid transform (rotation part not orthonormal or last row not 0 0 0 1)")
    return T
