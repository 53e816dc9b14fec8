"""URDF in and out for ZRP arms (docs/model.md, section 5).

Reading (:func:`read_urdf`) parses the XML with lxml and reads the links and the joints' type,
parent, child, ``<origin>``, ``<axis>``, ``<limit>`` and ``<mimic>``; everything else (visuals,
collisions, inertias, meshes, transmissions, Gazebo tags) is left alone, so meshes are never
loaded. The serial chain from ``base_link`` to ``tip_link`` (defaults: the root link and its
single leaf) is walked at q = 0: fixed joints fold into their neighbours; each revolute,
continuous or prismatic joint gives a ZRP axis, the joint frame's rotation times the URDF axis
(default ``1 0 0``, as the URDF specification says), through the joint frame's origin; the tip
link's frame gives ``R_h0`` and the end point. Joint names and limits are kept (continuous
joints, and joints without lower and upper limits, get :data:`~zrp_ga.model.robot.DEFAULT_LIMITS`).
Floating, planar and mimic joints in the chain are refused. URDF lengths are metres and angles
radians. The robot read carries the file (:class:`URDFSource` in ``robot.source``) so that the
calibrated arm can be written back into it.

Writing (:func:`to_urdf`) has two forms.

- The arm was read from a URDF (``robot.source``): the output is that file with only the
  ``<origin>`` of the chain's movable joints and of the first fixed joint after the last one
  (the hand joint, which carries the calibrated hand) changed; names, links, visuals,
  collisions, inertias, limits, comments and every other joint stay as they were. Each link
  frame keeps its nominal orientation turned by the smallest rotation that takes its axis onto
  the calibrated one (so the ``<axis>`` text stays), and sits at the foot of the perpendicular
  from its nominal origin onto the calibrated axis (prismatic joints: at its nominal origin).
  Numbers that do not change (to 1e-15) keep their text. Only when the chain has no fixed joint
  after its last movable joint does the axis change (the tip link is then the hand); if the
  calibrated end point is off the last axis, a fixed joint ``calibrated_hand_joint`` to a new
  link ``calibrated_hand`` carries the rest, with a comment saying so.
- Otherwise a new URDF (ElementTree), the exact mapping with link frames world-aligned at
  q = 0: joint i has ``origin xyz = b0_i`` (from the previous joint's point), ``rpy = 0``,
  ``axis = u0_i``; the fixed ``hand_joint`` carries ``b0_{n+1}`` and ``rpy(R_h0)``. Links are
  ``base_link``, ``link_1`` .. ``link_n`` and ``hand``.

Both add, when given, the ``base`` transform as a new root link ``world`` with fixed joint
``base_joint`` and the ``tool`` transform as link ``tool`` with fixed joint ``tool_joint``
under the hand (names made unique if the file already uses them).

Errors are ValueErrors of one line naming the file and the line or the joint.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from zrp_ga.model import so3
from zrp_ga.model.dh import DHTable
from zrp_ga.model.robot import DEFAULT_LIMITS, MAX_ANGLE_RAD, MAX_LENGTH_M, ZRPRobot

if TYPE_CHECKING:
    from lxml import etree

Array = NDArray[np.float64]
log = logging.getLogger("zrp_ga")
_MOVABLE = {"revolute": "R", "continuous": "R", "prismatic": "P"}
_KINDS = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_FIXED_JOINTS = ("base_joint", "hand_joint", "tool_joint")  # names the new URDF uses


@dataclasses.dataclass(frozen=True)
class URDFSource:
    """The URDF an arm was read from: file name, text, and the chain's end links."""

    path: str
    text: str
    base_link: str
    tip_link: str


class _Joint(NamedTuple):
    """One ``<joint>`` as read: origin (4, 4), axis (3,) as written, limits None where absent."""

    name: str
    type: str
    parent: str
    child: str
    origin: Array
    axis: Array
    lower: float | None
    upper: float | None
    mimic: str | None
    line: int
    element: etree._Element  # the lxml element, for writing back


class _Urdf(NamedTuple):
    root: etree._Element  # lxml root element
    name: str
    links: list[str]
    joints: list[_Joint]


def read_urdf(
    path: str | Path, text: str | None = None, base_link: str | None = None, tip_link: str | None = None
) -> ZRPRobot:
    """The ZRP arm of the chain ``base_link`` .. ``tip_link`` of a URDF (module docstring).

    ``text``: the file's text if already read. Prefer :func:`zrp_ga.io.robot_files.read_robot`,
    which also checks the path.
    """
    path = Path(path)
    text = path.read_text() if text is None else text
    urdf = _parse(path, text)
    chain, base, tip = _chain(path, urdf, base_link, tip_link)
    robot = _zrp(path, urdf.name, chain, base, tip, URDFSource(str(path), text, base, tip))
    mass = mass_model(path, urdf, chain, robot)
    return robot if mass is None else robot.replace(mass=mass)


def mass_model(path: Path, urdf: _Urdf, chain: list[_Joint], robot: ZRPRobot):
    """The arm's mass model (:class:`zrp_ga.model.terms.MassModel`) from the ``<inertial>``
    elements of the links the chain moves: each link's mass at its centre (``<origin xyz>`` in the
    link's frame) at q = 0, summed into the joint that moves it (the last movable joint before it;
    links before the first movable joint carry no torque and are left out); None when no moved
    link has a mass."""
    from zrp_ga.model.terms import MassModel

    elements = {link.get("name"): link for link in urdf.root.findall("link")}
    n, T, k = robot.n, np.eye(4), -1
    masses, moments = np.zeros(n), np.zeros((n, 3))
    for joint in chain:
        T = T @ joint.origin
        if joint.type != "fixed":
            k += 1
        inertial = elements[joint.child].find("inertial") if joint.child in elements else None
        if k < 0 or inertial is None or inertial.find("mass") is None:
            continue
        try:
            m = float(inertial.find("mass").get("value"))
            origin = inertial.find("origin")
            xyz = np.array([float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()])
        except (TypeError, ValueError):
            raise ValueError(f"{path}, line {inertial.sourceline}: link {joint.child!r}: <inertial> needs <mass value=...> "
                             "and <origin xyz='x y z'> numbers") from None  # fmt: skip
        if xyz.shape != (3,) or not (np.isfinite(m) and m >= 0 and np.all(np.isfinite(xyz))):
            raise ValueError(f"{path}, line {inertial.sourceline}: link {joint.child!r}: <inertial>: a mass >= 0 and 3 finite numbers xyz")
        masses[k] += m
        moments[k] += m * (T[:3, :3] @ xyz + T[:3, 3])
    if not masses.any():
        return None
    points = np.cumsum(robot.b0[:n], axis=0)  # the point on each axis at q = 0
    centres = np.where(masses[:, None] > 0, moments / np.where(masses > 0, masses, 1.0)[:, None], points) - points
    return MassModel(masses, centres, source=f"URDF inertials ({path.name})")


def _parse(path: Path, text: str) -> _Urdf:
    """The links and joints of a URDF, checked: well-formed XML, a <robot name=...> root, named
    links and complete joints of a known type with sane numbers."""
    from lxml import etree

    try:
        root = etree.fromstring(text.encode("utf-8"))
    except etree.XMLSyntaxError as exc:
        line, column = exc.position
        raise ValueError(_one_line(f"{path}, line {line}, column {column}: malformed XML: {exc.msg}")) from None
    if root.tag != "robot" or not root.get("name"):
        got = f"got <{root.tag}>"
        raise ValueError(f"{path}, line {root.sourceline}: not a URDF: expected <robot name=...> as the root, {got}")
    links: dict[str, int] = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise ValueError(f"{path}, line {link.sourceline}: a <link> without a name")
        if name in links:
            raise ValueError(f"{path}, line {link.sourceline}: link {name!r}: name already used by the link on line {links[name]}")
        links[name] = link.sourceline
    joints: list[_Joint] = []
    for element in root.findall("joint"):
        name = element.get("name")
        where = f"{path}, line {element.sourceline}: joint {name!r}"
        if not name:
            raise ValueError(f"{path}, line {element.sourceline}: a <joint> without a name")
        for other in joints:
            if other.name == name:
                raise ValueError(f"{where}: name already used by the joint on line {other.line}")
        ends = {}
        for tag in ("parent", "child"):
            if element.find(tag) is None or not element.find(tag).get("link"):
                raise ValueError(f"{where}: missing <{tag} link=...>")
            ends[tag] = element.find(tag).get("link")
        kind = element.get("type")
        if not kind:
            raise ValueError(f"{where}: missing type")
        if kind not in _KINDS:
            raise ValueError(f"{where}: unknown type {kind!r} (URDF joint types: {', '.join(_KINDS)})")
        joints.append(_joint(where, element, name, kind, ends["parent"], ends["child"]))
    return _Urdf(root, root.get("name"), list(links), joints)


def _joint(where: str, element, name: str, kind: str, parent: str, child: str) -> _Joint:
    """The joint's numbers: the right count of finite, sane numbers (URDF defaults where absent)."""
    limit_bound = MAX_LENGTH_M if kind == "prismatic" else MAX_ANGLE_RAD
    values = {}
    for tag, attr, count, bound in (
        ("origin", "xyz", 3, MAX_LENGTH_M), ("origin", "rpy", 3, MAX_ANGLE_RAD), ("axis", "xyz", 3, MAX_LENGTH_M),
        ("limit", "lower", 1, limit_bound), ("limit", "upper", 1, limit_bound),
    ):
        found = element.find(tag)
        text = None if found is None else found.get(attr)
        if text is None:
            continue
        try:
            numbers = [float(v) for v in text.split()]
        except ValueError:
            raise ValueError(f"{where}: <{tag} {attr}={text!r}>: not numbers") from None
        if len(numbers) != count:
            raise ValueError(f"{where}: <{tag} {attr}={text!r}>: expected {count} number(s), got {len(numbers)}")
        if not np.all(np.isfinite(numbers)) or np.max(np.abs(numbers)) > bound:
            raise ValueError(f"{where}: <{tag} {attr}={text!r}>: not finite or absurd (beyond {bound:g} m or rad)")
        values[tag, attr] = np.array(numbers)
    mimic = element.find("mimic")
    lower, upper = (float(values[k][0]) if k in values else None for k in (("limit", "lower"), ("limit", "upper")))
    return _Joint(
        name, kind, parent, child,
        _transform(values.get(("origin", "xyz"), np.zeros(3)), values.get(("origin", "rpy"), np.zeros(3))),
        values.get(("axis", "xyz"), np.array([1.0, 0.0, 0.0])),
        lower, upper,
        None if mimic is None else mimic.get("joint", ""), element.sourceline, element,
    )


def _transform(xyz: ArrayLike, rpy: ArrayLike) -> Array:
    """4x4 transform of a URDF origin: ``R = Rz(yaw) Ry(pitch) Rx(roll)``."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_euler("xyz", rpy).as_matrix(), xyz
    return T


def _chain(path: Path, urdf: _Urdf, base_link: str | None, tip_link: str | None) -> tuple[list[_Joint], str, str]:
    """The joints from ``base_link`` to ``tip_link`` (defaults: the single root and leaf), base first."""
    links = urdf.links
    by_child, children = _tree(path, urdf)
    roots = [k for k in links if k not in by_child]
    base = base_link if base_link is not None else _only(path, roots, "root links", "base_link")
    _known(path, base, links, "base_link")
    below: list[str] = []
    todo = [base]
    while todo and len(below) <= len(links):
        below.append(todo.pop())
        todo += children[below[-1]]
    leaves = [k for k in below if not children[k]]
    tip = tip_link if tip_link is not None else _only(path, leaves, f"leaf links below {base!r}", "tip_link")
    _known(path, tip, links, "tip_link")
    chain: list[_Joint] = []
    link = tip
    while link != base:
        if link not in by_child or len(chain) > len(urdf.joints):
            raise ValueError(f"{path}: tip_link {tip!r} is not below base_link {base!r}")
        chain.append(by_child[link])
        link = chain[-1].parent
    return chain[::-1], base, tip


def _tree(path: Path, urdf: _Urdf) -> tuple[dict[str, _Joint], dict[str, list[str]]]:
    """child link -> its joint, and link -> child links; joints must name known links, a link one parent."""
    by_child: dict[str, _Joint] = {}
    children: dict[str, list[str]] = {link: [] for link in urdf.links}
    for joint in urdf.joints:
        for link in (joint.parent, joint.child):
            if link not in children:
                raise _joint_error(path, joint, f"unknown link {link!r}")
        if joint.child in by_child:
            raise _joint_error(path, joint, f"link {joint.child!r} is already the child of {by_child[joint.child].name!r}")
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


def _zrp(path: Path, name: str, chain: list[_Joint], base: str, tip: str, source: URDFSource) -> ZRPRobot:
    """Walk the chain at q = 0 (module docstring)."""
    T = np.eye(4)
    points, axes, types, names, limits = [], [], [], [], []
    for joint in chain:
        T = T @ joint.origin
        if joint.type == "fixed":
            continue
        if joint.type not in _MOVABLE:
            kinds = "only revolute, continuous, prismatic and fixed joints can be read"
            raise _joint_error(path, joint, f"a {joint.type} joint; {kinds}")
        if joint.mimic is not None:
            raise _joint_error(path, joint, f"mimics {joint.mimic!r}; mimic joints cannot be read")
        length = np.linalg.norm(joint.axis)
        if length < 1e-12:
            raise _joint_error(path, joint, "axis of length zero")
        points.append(T[:3, 3].copy())
        axes.append(T[:3, :3] @ joint.axis / length)
        types.append(_MOVABLE[joint.type])
        names.append(joint.name)
        limits.append(_limits(path, joint))
    if not axes:
        raise ValueError(f"{path}: no movable joint between base_link {base!r} and tip_link {tip!r}")
    b0 = np.diff(np.vstack([np.zeros(3), *points, T[:3, 3]]), axis=0)
    try:
        return ZRPRobot(
            u0=np.array(axes), b0=b0, R_h0=T[:3, :3], joint_types="".join(types), name=name, joint_names=tuple(names),
            limits=np.array(limits, dtype=float), normalize=True, source=source,
        )
    except ValueError as exc:  # not expected after the checks above; named all the same
        raise ValueError(_one_line(f"{path}: {exc}")) from None


def _limits(path: Path, joint: _Joint) -> tuple[float, float]:
    """(lower, upper) of a movable joint, defaults where the file gives none (continuous joints)."""
    lower, upper = DEFAULT_LIMITS[_MOVABLE[joint.type]]
    if joint.type != "continuous":
        lower = lower if joint.lower is None else joint.lower
        upper = upper if joint.upper is None else joint.upper
    if not lower < upper:
        raise _joint_error(path, joint, f"limit lower {lower:g} is not below upper {upper:g}")
    return lower, upper


def _joint_error(path: Path, joint: _Joint, message: str) -> ValueError:
    return ValueError(_one_line(f"{path}, line {joint.line}: joint {joint.name!r}: {message}"))


def _one_line(text: str) -> str:
    return " ".join(text.split())


def to_urdf(
    robot: ZRPRobot, path: str | Path | None = None, base: ArrayLike | None = None, tool: ArrayLike | None = None
) -> str:
    """URDF text of a ZRP arm; also written to ``path``.

    An arm read from a URDF is written into that file, only the calibrated joints' origins (and
    axes where needed) changed; other arms get a new URDF of the exact mapping of
    docs/model.md, section 5 (module docstring). ``base`` (4x4): pose of the robot's world frame
    (the chain's base link) in an outer frame, added as link ``world`` and fixed joint
    ``base_joint``; ``tool`` (4x4): pose of a tool frame in the hand frame, added as link
    ``tool`` and fixed joint ``tool_joint``. A new URDF has the robot's joint names
    (``joint_<i>`` if it has none) and limits (:attr:`ZRPRobot.joint_limits`); effort and
    velocity limits are unknown there and written as 0.

    >>> from zrp_ga.io import presets
    >>> "<axis xyz=\\"0.0 0.0 1.0\\" />" in to_urdf(presets.get("puma560"))
    True
    """
    base = None if base is None else check_transform(base, "base")
    tool = None if tool is None else check_transform(tool, "tool")
    source = getattr(robot, "source", None)
    text = None
    if isinstance(source, URDFSource):
        text = _patched(robot, source, base, tool)
    if text is None:
        text = _new_urdf(robot, base, tool)
    if path is not None:
        Path(path).write_text(text)
    return text


# --- the user's URDF with the calibrated joints --------------------------------------------------
def _patched(robot: ZRPRobot, source: URDFSource, base: Array | None, tool: Array | None) -> str | None:
    """The source URDF with the calibrated chain (module docstring); None (and a warning) when
    the arm's joints are not the chain's."""
    from lxml import etree

    path = Path(source.path)
    urdf = _parse(path, source.text)
    chain, _, _ = _chain(path, urdf, source.base_link, source.tip_link)
    movable = [m for m, joint in enumerate(chain) if joint.type != "fixed"]
    kinds = "".join(_MOVABLE.get(chain[m].type, "?") for m in movable)
    if tuple(chain[m].name for m in movable) != robot.joint_names or kinds != robot.joint_types:
        log.warning("%s: the arm's joints are no longer the file's chain; writing a new URDF instead", path)
        return None
    points = np.cumsum(robot.b0, axis=0)  # points[k]: on axis k+1; points[n]: the end point
    hand = _pose(robot.R_h0, points[-1])
    last = movable[-1]
    hand_at = last + 1 if last + 1 < len(chain) else None  # the fixed joint carrying the hand
    nominal, T, hand_link = np.eye(4), np.eye(4), source.tip_link
    added: list[etree._Element] = []
    for m, joint in enumerate(chain):
        nominal = nominal @ joint.origin
        if m == hand_at:
            F = hand @ np.linalg.inv(_product(j.origin for j in chain[m + 1:]))
        elif joint.type == "fixed":
            T = T @ joint.origin
            continue
        else:
            k = movable.index(m)
            F = _calibrated_frame(nominal, joint, points[k], robot.u0[k])
            if m == last and hand_at is None:  # the tip link is the hand
                F, added = _hand_on_last_axis(joint, hand, points[k], robot.u0[k], urdf)
                hand_link = added[-1].get("name") if added else hand_link
            elif not reads_small((np.linalg.inv(T) @ F)[:3, :3], _nominal_rpy(joint)):
                F = _turn_kept(joint, T, F, robot.u0[k])
        _set_origin(joint, np.linalg.inv(T) @ F)
        T = F
    root = urdf.root
    links, joints = set(urdf.links), {j.name for j in urdf.joints}
    if base is not None:
        if any(j.child == source.base_link for j in urdf.joints):
            log.warning("%s: base_link %r has a parent joint; the base transform is in the frames file only",
                        path, source.base_link)
        else:
            world = _free("world", links)
            added += [etree.Comment(" added by zrp_ga: the calibrated pose of the robot's base in the measurement frame "),
                      _fixed_element(_free("base_joint", joints), world, source.base_link, base),
                      etree.Element("link", name=world)]  # fmt: skip
    if tool is not None:
        name = _free("tool", links)
        added += [etree.Comment(" added by zrp_ga: the calibrated tool frame in the hand frame "),
                  etree.Element("link", name=name), _fixed_element(_free("tool_joint", joints), hand_link, name, tool)]  # fmt: skip
    _append(root, added)
    return _text_around(source.text, root, etree.tostring(root, encoding="unicode"))


def _text_around(text: str, root, written: str) -> str:
    """The root element as written, inside the source's own text before and after it (XML
    declaration, comments) and with the source's own start tag (attribute order kept)."""
    lines = text.splitlines(keepends=True)
    begin = text.rfind("<robot", 0, sum(len(line) for line in lines[: root.sourceline]))  # the tag may span lines
    close = text.rfind("</robot>")
    if begin < 0 or close < 0:  # not expected (an empty <robot/> has no chain): lxml's own text
        return '<?xml version="1.0"?>\n' + written + "\n"
    end = text.index(">", begin) + 1
    return text[:end] + written[written.index(">") + 1:] + text[close + len("</robot>"):]


def _calibrated_frame(nominal: Array, joint: _Joint, point: Array, u: Array) -> Array:
    """World pose at q = 0 of a movable joint's child link on the calibrated axis (point, u):
    the nominal pose turned by the smallest rotation taking its axis onto u, moved to the foot
    of the perpendicular from its origin onto the axis (prismatic: not moved)."""
    F = nominal.copy()
    a = nominal[:3, :3] @ joint.axis / np.linalg.norm(joint.axis)
    c = np.cross(a, u)
    angle = np.arctan2(np.linalg.norm(c), np.dot(a, u))
    if np.linalg.norm(c) > 0:
        F[:3, :3] = Rotation.from_rotvec(c / np.linalg.norm(c) * angle).as_matrix() @ nominal[:3, :3]
    if joint.type != "prismatic":
        F[:3, 3] = point + np.dot(nominal[:3, 3] - point, u) * u
    return F


def _turn_kept(joint: _Joint, T: Array, F: Array, u: Array) -> Array:
    """The child frame at F's origin turned from the parent frame T by the joint's nominal
    rotation, the ``<axis>`` written in it: where the nominal ``rpy`` is next to pitch = +-90
    degrees (:func:`reads_small`), the calibrated turn then reads in the axis, not in roll and
    yaw of half a radian each."""
    from lxml import etree

    out = F.copy()
    out[:3, :3] = T[:3, :3] @ joint.origin[:3, :3]
    axis = joint.element.find("axis")
    if axis is None:
        axis = etree.SubElement(joint.element, "axis")
    axis.set("xyz", _numbers(out[:3, :3].T @ u))
    log.info("joint %r: its origin's pitch is next to +-90 degrees, where roll-pitch-yaw cannot show a small turn; "
             "its rpy kept and its <axis> written in the calibrated frame", joint.name)
    return out


def _hand_on_last_axis(joint: _Joint, hand: Array, point: Array, u: Array, urdf: _Urdf) -> tuple[Array, list]:
    """The last movable joint's child is the tip: its frame is the hand's, moved onto the axis
    (revolute), the axis written in it; an end point off the axis goes to a new fixed joint."""
    from lxml import etree

    F = hand.copy()
    if joint.type != "prismatic":
        F[:3, 3] = point + np.dot(hand[:3, 3] - point, u) * u
    axis = joint.element.find("axis")
    if axis is None:
        axis = etree.SubElement(joint.element, "axis")
    axis.set("xyz", _numbers(F[:3, :3].T @ u))
    rest = F[:3, :3].T @ (hand[:3, 3] - F[:3, 3])
    if np.linalg.norm(rest) <= 1e-12:
        return F, []
    log.warning("joint %r: the calibrated end point is %.3g m off its axis; written as the new fixed joint "
                "calibrated_hand_joint (to link calibrated_hand)", joint.name, np.linalg.norm(rest))
    name = _free("calibrated_hand", set(urdf.links))
    return F, [etree.Comment(" added by zrp_ga: the calibrated end point, off the last joint's axis "),
               _fixed_element(_free("calibrated_hand_joint", {j.name for j in urdf.joints}), joint.child, name, _pose(np.eye(3), rest)),
               etree.Element("link", name=name)]  # fmt: skip


def _set_origin(joint: _Joint, T: NDArray[np.floating]) -> None:
    """Write T into the joint's <origin>, keeping the text of the parts that did not change (1e-14)."""
    from lxml import etree

    origin = joint.element.find("origin")
    if origin is None:
        if np.abs(T - np.eye(4)).max() <= 1e-14:
            return
        origin = etree.SubElement(joint.element, "origin")
    if np.abs(T[:3, 3] - joint.origin[:3, 3]).max() > 1e-14:
        origin.set("xyz", _numbers(T[:3, 3]))
    if np.abs(T[:3, :3] - joint.origin[:3, :3]).max() > 1e-14:
        origin.set("rpy", _numbers(rpy_near(T[:3, :3], _nominal_rpy(joint))))


def _nominal_rpy(joint: _Joint) -> Array:
    """The joint's ``<origin rpy>`` as written in the source (0 0 0 where absent)."""
    origin = joint.element.find("origin")
    text = None if origin is None else origin.get("rpy")
    return np.zeros(3) if text is None else np.array([float(v) for v in text.split()])


def _fixed_element(name: str, parent: str, child: str, T: Array):
    from lxml import etree

    joint = etree.Element("joint", name=name, type="fixed")
    etree.SubElement(joint, "parent", link=parent)
    etree.SubElement(joint, "child", link=child)
    etree.SubElement(joint, "origin", xyz=_numbers(T[:3, 3]), rpy=_numbers(so3.rpy(T[:3, :3])))
    return joint


def _append(root, elements: list) -> None:
    """Append elements to the root, one a line, indented as its first child."""
    if not elements:
        return
    indent = root.text if root.text and not root.text.strip() else "\n  "
    last = root[-1] if len(root) else None
    for element in elements:
        if last is None:
            root.text = indent
        else:
            last.tail = indent
        root.append(element)
        last = element
    assert last is not None  # elements is not empty
    last.tail = "\n"


def _free(name: str, taken: set[str]) -> str:
    """``name``, or ``name_2``, ``name_3``, ... if taken."""
    k, out = 1, name
    while out in taken:
        k += 1
        out = f"{name}_{k}"
    return out


def _product(transforms) -> Array:
    T = np.eye(4)
    for A in transforms:
        T = T @ A
    return T


def _pose(R: Array, p: Array) -> Array:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


# --- a new URDF ----------------------------------------------------------------------------------
def _new_urdf(robot: ZRPRobot, base: Array | None, tool: Array | None) -> str:
    """The exact mapping with world-aligned link frames (module docstring), as ElementTree writes
    it indented (``ET.indent``, ``ET.tostring``), written out as text: a run of a sweep writes
    one at its end."""
    names = robot.joint_names or tuple(f"joint_{i + 1}" for i in range(robot.n))
    clash = sorted(set(names) & set(_FIXED_JOINTS))
    if clash:
        raise ValueError(f"joint names {', '.join(clash)}: reserved for the URDF's fixed joints")
    lines = ['<?xml version="1.0"?>', f"<robot name={_attr(robot.name)}>"]
    if base is not None:
        lines.append('  <link name="world" />')
        lines += _urdf_joint("base_joint", "fixed", "world", "base_link", base)
    lines.append('  <link name="base_link" />')
    parent = "base_link"
    for i in range(robot.n):
        lines.append(f'  <link name="link_{i + 1}" />')
        kind = "revolute" if robot.joint_types[i] == "R" else "prismatic"
        joint = _urdf_joint(names[i], kind, parent, f"link_{i + 1}", _pose(np.eye(3), robot.b0[i]))
        lower, upper = robot.joint_limits[i]
        joint[-1:-1] = [f'    <axis xyz="{_numbers(robot.u0[i])}" />',
                        f'    <limit lower="{float(lower)!r}" upper="{float(upper)!r}" effort="0" velocity="0" />']
        lines += joint
        parent = f"link_{i + 1}"
    lines.append('  <link name="hand" />')
    near = so3.rpy(robot.source.to_robot().R_h0) if isinstance(robot.source, DHTable) else None  # the nominal's hand
    lines += _urdf_joint("hand_joint", "fixed", parent, "hand", _pose(robot.R_h0, robot.b0[-1]), near)
    if tool is not None:
        lines.append('  <link name="tool" />')
        lines += _urdf_joint("tool_joint", "fixed", "hand", "tool", tool)
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _urdf_joint(name: str, kind: str, parent: str, child: str, T: Array, near: Array | None = None) -> list[str]:
    """The lines of a joint element (origin last before the closing tag); ``near``: the rpy
    triple to write the rotation nearest to (:func:`rpy_near`)."""
    return [f"  <joint name={_attr(name)} type={_attr(kind)}>", f"    <parent link={_attr(parent)} />",
            f"    <child link={_attr(child)} />",
            f'    <origin xyz="{_numbers(T[:3, 3])}" rpy="{_numbers(rpy_near(T[:3, :3], near))}" />', "  </joint>"]


@functools.lru_cache(maxsize=1024)
def _attr(value: str) -> str:
    """``value`` as ElementTree writes it as an attribute value: quoted and escaped."""
    return ET.tostring(ET.Element("a", v=value), encoding="unicode").removeprefix("<a v=").removesuffix(" />")


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


def rpy_near(R: ArrayLike, near: ArrayLike | None = None) -> Array:
    """Roll, pitch, yaw (3,), rad, of the rotation R (3, 3) (URDF's ``Rz(yaw) Ry(pitch) Rx(roll)``,
    :func:`zrp_ga.model.so3.rpy`), the triple of its two families (``(r, p, y)`` and
    ``(r + pi, pi - p, y + pi)``) and their turns by 2 pi nearest ``near`` (3,), rad (largest
    difference), so that a rotation near a nominal triple reads as that triple plus a small
    change. Next to pitch = +-90 degrees no triple may be near: see :func:`reads_small`.

    >>> np.round(rpy_near(Rotation.from_euler("xyz", [3.0, 0.1, -3.0]).as_matrix(), [3.0, 0.1, 3.3]), 6).tolist()
    [3.0, 0.1, 3.283185]
    """
    r = so3.rpy(R)
    if near is None:
        return r
    near = np.asarray(near, dtype=float)
    candidates = [near + np.angle(np.exp(1j * (c - near))) for c in (r, r + [np.pi, np.pi - 2 * r[1], np.pi])]
    return min(candidates, key=lambda c: float(np.abs(c - near).max())) + 0.0


def reads_small(R: ArrayLike, near: ArrayLike, factor: float = 10.0) -> bool:
    """Whether :func:`rpy_near` writes R as ``near`` plus changes of at most ``factor`` times the
    angle between R and the rotation of ``near`` (1e-12 rad at least): false next to pitch =
    +-90 degrees, where roll and yaw take large opposite turns for a small turn about the
    rotated z axis."""
    R0 = Rotation.from_euler("xyz", near).as_matrix()
    angle = np.linalg.norm(Rotation.from_matrix(R0.T @ np.asarray(R)).as_rotvec())
    return bool(float(np.abs(rpy_near(R, near) - np.asarray(near)).max()) <= factor * angle + 1e-12)
