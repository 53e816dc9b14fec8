"""Robot files in and out: DH / modified-DH table files, ZRP YAML files and URDF.

- :func:`read_robot` reads any of the three into a :class:`~zrp_ga.model.robot.ZRPRobot`;
  :func:`read_dh` reads a DH table file into a :class:`~zrp_ga.model.dh.DHTable`.
- :func:`to_urdf`, :func:`dh_to_yaml` (with :func:`~zrp_ga.model.dh.to_dh`, re-exported here) and
  :meth:`ZRPRobot.to_yaml` write them; :func:`write_robot_files` writes all of them at once.

**DH table file** (YAML; keys as below, anything else is refused)::

    name: myarm                        # optional; default: the file name without suffix
    convention: dh                     # dh: standard (distal), A_i = Rz(theta) Tz(d) Tx(a) Rx(alpha)
                                       # mdh: modified (proximal, Craig), A_i = Rx(alpha) Tx(a) Rz(theta) Tz(d),
                                       #      where row i holds a_{i-1} and alpha_{i-1}
    units: {length: mm, angle: deg}    # required; length m or mm, angle rad or deg
    joints:                            # one row per joint, from the base
      - {name: joint_1, type: R, a: 0, alpha: 90, d: 400, theta: 0, limits: [-170, 170]}
      - {name: slide, type: P, a: 0, alpha: 0, d: 0, theta: -90, limits: [300, 1200]}
    base: {xyz: [0, 0, 0], rpy: [0, 0, 0]}   # optional: pose of DH frame 0 in the world
    tool: {xyz: [0, 0, 100], quaternion_xyzw: [0, 0, 0, 1]}   # optional: hand pose in frame n

Joint rows: ``type`` R (revolute: the joint angle is ``theta + q``) or P (prismatic: the offset
along z is ``d + q``, theta fixed); ``a``, ``alpha``, ``d`` required; ``theta`` defaults to 0,
``beta`` (angle unit) to 0: a row with ``beta`` is a Hayati row for nearly parallel axes, with
``Ry(beta)`` after ``Rx(alpha)`` (:mod:`zrp_ga.model.dh`; :func:`to_dh` writes such rows and says why),
``name`` to ``joint_<i>``, ``limits`` (lower < upper, in the angle unit for R and the length unit
for P) to :data:`~zrp_ga.model.robot.DEFAULT_LIMITS`. ``base`` and ``tool`` take ``xyz`` (length unit, default
0) with either ``rpy`` (angle unit; URDF's roll-pitch-yaw, ``R = Rz(yaw) Ry(pitch) Rx(roll)``)
or ``quaternion_xyzw`` (x, y, z, w: scalar last, as scipy and ROS; normalised if within 1e-3 of
unit length), or ``matrix``: a 4x4 homogeneous matrix (translation in the length unit; rotation
orthonormal to 1e-6). Numbers are plain YAML numbers (``1e-3`` too, which YAML 1.1 would read as
text); beyond 1e4 m or 100 rad they are refused as absurd.

**ZRP YAML**: what :meth:`ZRPRobot.to_yaml` writes (keys ``u0``, ``b0``, ...; metres).

**URDF**: read with lxml (meshes and visuals are never loaded), the mapping of docs/model.md,
section 5; an arm read from a URDF is written back into that file with only its calibrated
joints' origins changed; see :mod:`zrp_ga.io.urdf` (its :func:`~zrp_ga.io.urdf.to_urdf` is re-exported
here).

Every bad input raises ValueError with one line naming the file and the line and column (YAML),
the line (XML) or the joint, and what is wrong.
"""

from __future__ import annotations

import functools
import logging
import math
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from zrp_ga.core.errors import to_log_files
from zrp_ga.core.fileio import write_csv
from zrp_ga.core.files import regular_file
from zrp_ga.io import records, ros_calibration
from zrp_ga.io.urdf import URDFSource, check_transform, read_urdf, rpy_near, to_urdf
from zrp_ga.model import so3
from zrp_ga.model.dh import CONVENTIONS, DHMismatch, DHTable, nominal_tables, tables, to_dh
from zrp_ga.model.dh import corrections as dh_corrections
from zrp_ga.model.robot import DEFAULT_LIMITS, MAX_ANGLE_RAD, MAX_LENGTH_M, ZRPRobot

__all__ = ["DHMismatch", "DHTable", "dh_to_yaml", "read_dh", "read_robot", "to_dh", "to_urdf", "write_robot_files"]

Array = NDArray[np.float64]
log = logging.getLogger("zrp_ga")
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180}


def read_robot(path: str | Path, base_link: str | None = None, tip_link: str | None = None) -> ZRPRobot:
    """The robot in a DH table file, a ZRP YAML file or a URDF (module docstring).

    ``.urdf`` and ``.xml`` files are URDF, ``.yaml`` and ``.yml`` files a DH table (key
    ``joints``) or a ZRP robot (key ``u0``); other suffixes are URDF if the text starts with
    ``<``. ``base_link`` and ``tip_link`` choose the chain in a URDF (defaults: the root link and
    its single leaf).

    >>> from zrp_ga.io import presets
    >>> read_robot(presets.path("puma560"))
    ZRPRobot(name='puma560', n=6, joint_types='RRRRRR')
    """
    path, text = _read_text(path)
    if _is_urdf(path, text):
        return read_urdf(path, text, base_link, tip_link)
    if base_link is not None or tip_link is not None:
        raise ValueError(f"{path}: base_link and tip_link apply to URDF files only")
    doc = _Yaml(path, text)
    top = doc.mapping(doc.root, "the file")
    if "joints" in top:
        table = _dh_table(doc)
        return table.to_robot().replace(source=table)  # the table read: DH names in problem.fixed
    if "u0" in top:
        return _zrp_robot(doc, top)
    raise doc.error(doc.root, "neither a DH table (key 'joints') nor a ZRP robot (keys 'u0', 'b0')")


def read_dh(path: str | Path) -> DHTable:
    """The table in a DH table file (module docstring), in metres and radians."""
    return _dh_table(_Yaml(*_read_text(path)))


def _read_text(path: str | Path) -> tuple[Path, str]:
    path = regular_file(path, "a robot file (.yaml, .yml or .urdf)")
    try:
        return path, path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (not UTF-8)") from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror or exc})") from None


def _is_urdf(path: Path, text: str) -> bool:
    if path.suffix.lower() == ".xacro":
        raise ValueError(f"{path}: a xacro file; expand it to URDF first (xacro {path.name} > robot.urdf)")
    if path.suffix.lower() in (".yaml", ".yml"):
        return False
    return path.suffix.lower() in (".urdf", ".xml") or text.lstrip().startswith("<")


# --- YAML with line and column ----------------------------------------------------------------
class _Yaml:
    """A YAML document composed with its node marks, so that errors name line and column."""

    def __init__(self, path: Path, text: str) -> None:
        self.path = path
        try:
            self.root = yaml.compose(text, Loader=yaml.SafeLoader)
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            raise self.error(mark, f"malformed YAML: {exc.problem or exc.context}") from None
        except yaml.YAMLError as exc:
            raise ValueError(_one_line(f"{path}: malformed YAML ({exc})")) from None
        if self.root is None:
            raise ValueError(f"{path}: empty file")

    def error(self, where: yaml.Node | yaml.Mark, message: str) -> ValueError:
        """ValueError naming the file, the line and column of ``where`` and the message."""
        m = where.start_mark if isinstance(where, yaml.Node) else where
        return ValueError(_one_line(f"{self.path}, line {m.line + 1}, column {m.column + 1}: {message}"))

    def mapping(self, node: yaml.Node, what: str, known: tuple[str, ...] | None = None) -> dict[str | None, yaml.Node]:
        """Key -> value node of a mapping node; unknown (if ``known`` is given) or repeated keys
        refused (None: a key that is not text, where ``known`` is not given)."""
        if not isinstance(node, yaml.MappingNode):
            raise self.error(node, f"{what}: expected a mapping (key: value)")
        out: dict[str | None, yaml.Node] = {}
        for key_node, value in node.value:
            key = key_node.value if isinstance(key_node, yaml.ScalarNode) else None
            if known is not None and key not in known:
                raise self.error(key_node, f"{what}: unknown key {key!r} (known: {', '.join(known)})")
            if key in out:
                raise self.error(key_node, f"{what}: key {key!r} given twice")
            out[key] = value
        return out

    def need(self, mapping: dict[str | None, yaml.Node], node: yaml.Node, key: str, what: str) -> yaml.Node:
        """The value of a required key."""
        if key not in mapping:
            raise self.error(node, f"{what}: missing key {key!r}")
        return mapping[key]

    def text(self, node: yaml.Node, what: str, choices: tuple[str, ...] | None = None) -> str:
        if not isinstance(node, yaml.ScalarNode) or not node.value.strip():
            raise self.error(node, f"{what}: expected a name")
        if choices is not None and node.value not in choices:
            raise self.error(node, f"{what}: {node.value!r}, expected one of {', '.join(choices)}")
        return node.value

    def number(self, node: yaml.Node, what: str, scale: float = 1.0, bound: float = MAX_LENGTH_M) -> float:
        """A plain number times ``scale`` (to SI units); finite and below ``bound`` (SI) in size."""
        plain_str = node.tag == "tag:yaml.org,2002:str" and node.style is None  # 1e-3: a string in YAML 1.1
        if not isinstance(node, yaml.ScalarNode) or not (node.tag.endswith((":int", ":float")) or plain_str):
            raise self.error(node, f"{what}: expected a number")
        try:
            value = float(node.value if plain_str else yaml.constructor.SafeConstructor().construct_object(node))
        except ValueError:
            raise self.error(node, f"{what}: expected a number, got {node.value!r}") from None
        if not np.isfinite(value):
            raise self.error(node, f"{what}: {node.value} is not a finite number")
        if abs(value * scale) > bound:
            raise self.error(node, f"{what}: {node.value} is absurd (more than {bound:g} in SI units)")
        return value * scale

    def numbers(
        self, node: yaml.Node, what: str, count: int, scale: float = 1.0, bound: float = MAX_LENGTH_M
    ) -> Array:
        """A list of ``count`` numbers (see :meth:`number`)."""
        if not isinstance(node, yaml.SequenceNode) or len(node.value) != count:
            got = f"{len(node.value)} entries" if isinstance(node, yaml.SequenceNode) else "no list"
            raise self.error(node, f"{what}: expected a list of {count} numbers, got {got}")
        return np.array([self.number(v, f"{what}[{k}]", scale, bound) for k, v in enumerate(node.value)])


def _one_line(text: str) -> str:
    return " ".join(text.split())


# --- DH table files ---------------------------------------------------------------------------
def _dh_table(doc: _Yaml) -> DHTable:
    """The DH table of a composed DH file (module docstring)."""
    top = doc.mapping(doc.root, "the file", ("name", "convention", "units", "joints", "base", "tool"))
    convention = doc.text(doc.need(top, doc.root, "convention", "the file"), "convention", CONVENTIONS)
    length, angle = _units(doc, doc.need(top, doc.root, "units", "the file (e.g. units: {length: m, angle: deg})"))
    nodes = doc.need(top, doc.root, "joints", "the file")
    if not isinstance(nodes, yaml.SequenceNode) or not nodes.value:
        raise doc.error(nodes, "joints: expected a list of joint rows, one per joint")
    rows = [_dh_row(doc, node, i, length, angle) for i, node in enumerate(nodes.value)]
    beta = np.array([row.beta for row in rows])
    names = [row.name for row in rows]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise doc.error(nodes.value[i], f"joint {i + 1}: name {name!r} is joint {names.index(name) + 1}'s already")
    limits = None
    if any(row.limits is not None for row in rows):
        limits = np.array([DEFAULT_LIMITS[row.type] if row.limits is None else row.limits for row in rows], dtype=float)
    poses = {key: _pose(doc, top[key], key, length, angle) for key in ("base", "tool") if key in top}
    name = doc.text(top["name"], "name") if "name" in top else doc.path.stem
    a, alpha, d, theta = (np.array([getattr(row, k) for row in rows]) for k in ("a", "alpha", "d", "theta"))
    types = "".join(row.type for row in rows)
    try:
        return DHTable(
            convention, a, alpha, d, theta, types, name=name, joint_names=tuple(names), limits=limits, beta=beta, **poses
        )
    except ValueError as exc:  # not expected after the checks above; named all the same
        raise doc.error(doc.root, str(exc)) from None


class _Row(NamedTuple):
    """One joint row of a DH file, SI units."""

    name: str
    type: str
    a: float
    alpha: float
    d: float
    theta: float
    limits: Array | None
    beta: float


def _units(doc: _Yaml, node: yaml.Node) -> tuple[float, float]:
    """(metres per length unit, radians per angle unit) of a ``units`` mapping."""
    units = doc.mapping(node, "units", ("length", "angle"))
    length = doc.text(doc.need(units, node, "length", "units"), "units: length", tuple(LENGTH_UNITS))
    angle = doc.text(doc.need(units, node, "angle", "units"), "units: angle", tuple(ANGLE_UNITS))
    return LENGTH_UNITS[length], ANGLE_UNITS[angle]


def _dh_row(doc: _Yaml, node: yaml.Node, i: int, length: float, angle: float) -> _Row:
    """Joint row i of a DH file; ``length``, ``angle``: metres and radians per file unit."""
    row = doc.mapping(node, f"joint {i + 1}", ("name", "type", "a", "alpha", "d", "theta", "beta", "limits"))
    name = doc.text(row["name"], f"joint {i + 1}: name") if "name" in row else f"joint_{i + 1}"
    what = f"joint {i + 1} ({name})"
    kind = doc.text(doc.need(row, node, "type", what), f"{what}: type", ("R", "P"))
    a, d = (doc.number(doc.need(row, node, k, what), f"{what}: {k}", length) for k in ("a", "d"))
    alpha = doc.number(doc.need(row, node, "alpha", what), f"{what}: alpha", angle, MAX_ANGLE_RAD)
    theta = doc.number(row["theta"], f"{what}: theta", angle, MAX_ANGLE_RAD) if "theta" in row else 0.0
    beta = doc.number(row["beta"], f"{what}: beta", angle, MAX_ANGLE_RAD) if "beta" in row else 0.0
    limits = None
    if "limits" in row:
        unit, bound = (angle, MAX_ANGLE_RAD) if kind == "R" else (length, MAX_LENGTH_M)
        limits = doc.numbers(row["limits"], f"{what}: limits", 2, unit, bound)
        if not limits[0] < limits[1]:
            raise doc.error(row["limits"], f"{what}: limits: lower must be below upper")
    return _Row(name, kind, a, alpha, d, theta, limits, beta)


def _pose(doc: _Yaml, node: yaml.Node, what: str, length: float, angle: float) -> Array:
    """4x4 transform of a ``base`` or ``tool`` entry (module docstring), SI units."""
    keys = doc.mapping(node, what, ("xyz", "rpy", "quaternion_xyzw", "matrix"))
    if "matrix" in keys:
        if len(keys) > 1:
            raise doc.error(node, f"{what}: give either matrix or xyz with rpy or quaternion_xyzw")
        return _matrix(doc, keys["matrix"], f"{what}: matrix", length)
    if "rpy" in keys and "quaternion_xyzw" in keys:
        raise doc.error(node, f"{what}: give either rpy or quaternion_xyzw")
    T = np.eye(4)
    if "xyz" in keys:
        T[:3, 3] = doc.numbers(keys["xyz"], f"{what}: xyz", 3, length)
    if "rpy" in keys:
        rpy = doc.numbers(keys["rpy"], f"{what}: rpy", 3, angle, MAX_ANGLE_RAD)
        T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF's convention
    if "quaternion_xyzw" in keys:
        q = doc.numbers(keys["quaternion_xyzw"], f"{what}: quaternion_xyzw", 4, 1.0, 2.0)
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            norm = np.linalg.norm(q)
            raise doc.error(keys["quaternion_xyzw"], f"{what}: quaternion_xyzw has length {norm:.6g}, not 1")
        T[:3, :3] = Rotation.from_quat(q).as_matrix()
    return T


def _matrix(doc: _Yaml, node: yaml.Node, what: str, length: float) -> Array:
    """A 4x4 homogeneous matrix (translation in the length unit), rotation orthonormal to 1e-6."""
    if not isinstance(node, yaml.SequenceNode) or len(node.value) != 4:
        raise doc.error(node, f"{what}: expected 4 rows of 4 numbers")
    T = np.array([doc.numbers(row, f"{what} row {k + 1}", 4) for k, row in enumerate(node.value)])
    R = T[:3, :3]
    if np.abs(T[3] - [0, 0, 0, 1]).max() > 1e-9:
        raise doc.error(node.value[3], f"{what}: the last row must be 0 0 0 1")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        hint = "use xyz with rpy for rounded values"
        raise doc.error(node, f"{what}: not a rotation (R^T R != I to 1e-6, or det < 0); {hint}")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-12:
        T[:3, :3] = Rotation.from_matrix(R).as_matrix()  # the nearest rotation
    T[:3, 3] *= length
    return T


def dh_to_yaml(
    table: DHTable, path: str | Path | None = None, length: str = "m", angle: str = "deg", comment: str = "",
    near: DHTable | None = None,
) -> str:
    """Text of a DH table file (module docstring) in the given units, ``comment`` lines on top;
    also written to ``path`` if given. ``near``: the nominal table, whose base and tool ``rpy``
    triples those written are nearest (:func:`zrp_ga.io.urdf.rpy_near`). Each number is written as the shortest decimal within 8
    units in the last place of its value in the file's unit (0.0203, not 0.020300000000000012), so
    reading the file back gives the table to about 1e-15 relative.

    >>> from zrp_ga.io import presets
    >>> table, _ = to_dh(presets.get("ur10"))
    >>> print(dh_to_yaml(table).splitlines()[4])
      - {name: shoulder_pan_joint, type: R, a: 0.0, alpha: 90.0, d: 0.1273, theta: 0.0, limits: [-360.0, 360.0]}
    """
    if length not in LENGTH_UNITS or angle not in ANGLE_UNITS:
        raise ValueError(f"units: length {length!r}, angle {angle!r}; expected m or mm, rad or deg")
    L, A = LENGTH_UNITS[length], ANGLE_UNITS[angle]
    names = table.joint_names or tuple(f"joint_{i + 1}" for i in range(table.n))
    lines = [f"# {line}" if line else "#" for line in comment.splitlines()]
    if table.betas.any():
        link = {"dh": "Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)", "mdh": "Rx(alpha) Tx(a) Ry(beta) Rz(theta) Tz(d)"}
        lines.append(f"# Rows with beta are Hayati rows (nearly parallel axes): A = {link[table.convention]}")
    head = {"name": table.name, "convention": table.convention, "units": {"length": length, "angle": angle}}
    lines += [_yaml_text(head).rstrip(), "joints:"]
    n = table.n
    columns = [table.a / L, table.alpha / A, table.d / L, table.theta / A, table.betas / A]
    if table.limits is not None:
        columns += list((np.asarray(table.limits) / np.array([[A if kind == "R" else L] for kind in table.joint_types])).T)
    nominal = (None, None) if near is None else (so3.rpy(near.base[:3, :3]), so3.rpy(near.tool[:3, :3]))
    poses = [(T[:3, 3] / L, rpy_near(T[:3, :3], r) / A) for T, r in zip((table.base, table.tool), nominal)]
    numbers = _short(np.concatenate(columns + [v for pose in poses for v in pose]))  # all at once
    assert isinstance(numbers, list)  # an array's numbers
    a, alpha, d, theta, beta = (numbers[k * n:(k + 1) * n] for k in range(5))
    if table.limits is not None:
        limits = list(zip(numbers[5 * n:6 * n], numbers[6 * n:7 * n]))
    for i, kind in enumerate(table.joint_types):
        row = [_flow_text("name", names[i]), _flow_text("type", kind)]
        row += [f"{k}: {_yaml_float(v)}" for k, v in (("a", a[i]), ("alpha", alpha[i]), ("d", d[i]), ("theta", theta[i]))]
        if table.betas[i]:
            row.append(f"beta: {_yaml_float(beta[i])}")
        if table.limits is not None:
            row.append(f"limits: [{', '.join(map(_yaml_float, limits[i]))}]")
        lines.append("  - {" + ", ".join(row) + "}" + ("  # Hayati row" if table.betas[i] else ""))
    rest = numbers[len(numbers) - 12:]
    pose_text = {key: {"xyz": rest[6 * k:6 * k + 3], "rpy": rest[6 * k + 3:6 * k + 6]} for k, key in enumerate(("base", "tool"))}
    lines.append(_yaml_text(pose_text).rstrip())
    text = "\n".join(lines) + "\n"
    if path is not None:
        Path(path).write_text(text)
    return text


# A joint row is written as PyYAML writes it (a flow mapping on one line), without PyYAML for the
# numbers: a run writes two tables at its end, and PyYAML takes most of their time.
@functools.lru_cache(maxsize=1024)
def _flow_text(key: str, value: str) -> str:
    """``key: value`` as an entry of a flow mapping, quoted as PyYAML quotes it."""
    return records.yaml_text({key: value}, default_flow_style=True, width=10**9).strip()[1:-1]


def _yaml_float(x: float) -> str:
    """A float as PyYAML writes it (``yaml.representer.SafeRepresenter.represent_float``)."""
    if x != x:
        return ".nan"
    if x in (math.inf, -math.inf):
        return ".inf" if x > 0 else "-.inf"
    text = repr(x).lower()
    return text.replace("e", ".0e", 1) if "." not in text and "e" in text else text


# The YAML documents of the robot files (nested mappings of names, floats and lists of them) are
# written as ``records.yaml_text(data, sort_keys=False, default_flow_style=None)`` writes them,
# without PyYAML's representer (most of the time of a run's robot files): collections holding
# no collection in flow style, the rest in block style, flow collections wrapped as PyYAML wraps
# them (a new line, indented, before an item when the line is past 80 characters). Anything else
# (a name YAML would quote, a number that is not a float, an empty collection) goes to PyYAML.
_WIDTH, _INDENT = 80, 2  # PyYAML's best_width and best_indent


class _NotPlain(Exception):
    """A document :func:`_yaml_text` leaves to PyYAML."""


def _yaml_text(data: dict) -> str:
    """``records.yaml_text(data, sort_keys=False, default_flow_style=None)``, the same text."""
    lines: list[str] = []
    try:
        if not isinstance(data, dict) or not any(isinstance(v, (dict, list)) for v in data.values()):
            raise _NotPlain  # a mapping of scalars alone: PyYAML's flow mapping
        _block_mapping(data, 0, lines)
    except _NotPlain:
        return records.yaml_text(data, sort_keys=False, default_flow_style=None)
    return "\n".join(lines) + "\n"


def _block_mapping(data: dict, indent: int, lines: list[str]) -> None:
    if not isinstance(data, dict) or not data:
        raise _NotPlain
    for key, value in data.items():
        head = " " * indent + _plain(key) + ":"
        if isinstance(value, (dict, list)) and not value:
            raise _NotPlain
        if isinstance(value, dict) and any(isinstance(v, (dict, list)) for v in value.values()):
            lines.append(head)
            _block_mapping(value, indent + _INDENT, lines)
        elif isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
            lines.append(head)  # a block sequence in a mapping: its dashes under the key
            for item in value:
                if not isinstance(item, list) or not item:
                    raise _NotPlain
                lines += _flow(" " * indent + "-", item, indent + _INDENT)
        elif isinstance(value, (dict, list)):
            lines += _flow(head, value, indent + _INDENT)
        else:
            lines.append(head + " " + _scalar(value))


def _flow(head: str, items: list | dict, indent: int) -> list[str]:
    """The lines of a flow sequence or mapping of scalars after ``head``, wrapped as PyYAML does."""
    is_map = isinstance(items, dict)
    texts = [f"{_plain(k)}: {_scalar(v)}" for k, v in items.items()] if isinstance(items, dict) else [_scalar(v) for v in items]
    lines, line = [], head + (" {" if is_map else " [")
    for k, text in enumerate(texts):
        if k:
            line += ","
        if len(line) > _WIDTH:
            lines.append(line)
            line = " " * indent + text
        else:
            line += (" " if k else "") + text
    lines.append(line + ("}" if is_map else "]"))
    return lines


def _scalar(value: object) -> str:
    if type(value) is float:
        return _yaml_float(value)
    if type(value) is str:
        return _plain(value)
    raise _NotPlain


@functools.lru_cache(maxsize=4096)
def _plain(text: str) -> str:
    """``text`` when PyYAML writes it plain (a name of letters, digits, ``_ . -`` read back as a
    string); otherwise the document goes to PyYAML."""
    if type(text) is not str or not _NAME.fullmatch(text):
        raise _NotPlain
    if yaml.resolver.Resolver().resolve(yaml.ScalarNode, text, (True, False)) != "tag:yaml.org,2002:str":
        raise _NotPlain
    return text


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*")


def _short(x: ArrayLike) -> float | list:
    """x (a number or array) as the floats of shortest decimal form within 8 units in the last place."""
    x = np.asarray(x, dtype=float)
    flat = x.ravel()
    best = flat + 0.0
    values = flat.tolist()
    search = []
    for i, (v, text) in enumerate(zip(values, map(repr, values))):
        if v in _SHORTENED:  # searched lately: a run writes two tables, of many of the same numbers
            best[i] = _SHORTENED[v]
        elif not _shortest_already(v, text):
            search.append(i)
    if search:  # the reprs of every candidate of these numbers in one pass; the first of the fewest
        # characters in nearest-first order (ties: the nearer, then the smaller)
        near = (flat[search, None] + np.spacing(flat[search])[:, None] * _STEPS)[:, _NEAREST_FIRST]
        lengths = np.fromiter(map(len, map(repr, near.ravel().tolist())), dtype=np.intp, count=near.size)
        best[search] = near[np.arange(len(near)), lengths.reshape(near.shape).argmin(axis=1)] + 0.0
        if len(_SHORTENED) > 4096:
            _SHORTENED.clear()
        _SHORTENED.update(zip(flat[search].tolist(), best[search].tolist()))
    return best.reshape(x.shape).tolist()


_SHORTENED: dict[float, float] = {}  # number -> _short(number), for the numbers searched lately


def _shortest_already(v: float, text: str) -> bool:
    """Whether ``v`` (``text``: its repr) is its own shortest candidate in :func:`_short`: 0, or a
    repr of at most 13 significant digits for 1e-90 < |v| < 1e11. Two floats within 8 units in
    the last place (1.8e-15 relative) that both had decimals of 13 digits or fewer would be
    at least 1e-14 apart (relative), so every other candidate needs 14 digits or more, hence
    as many characters or more (same sign, and at these magnitudes no fewer for the
    exponent, the leading zeros or the integer digits); ties go to v, the nearest."""
    if v == 0.0:
        return True
    if not 1e-90 < abs(v) < 1e11:
        return False
    digits = text.split("e")[0].replace("-", "").replace(".", "").strip("0")
    return len(digits) <= 13


_STEPS = np.arange(-8, 9)  # the candidates of _short: within 8 units in the last place
_NEAREST_FIRST = sorted(range(_STEPS.size), key=lambda j: (abs(_STEPS[j]), j))  # ties: the nearer, then the smaller


# --- ZRP YAML ----------------------------------------------------------------------------------
def _zrp_robot(doc: _Yaml, top: dict[str | None, yaml.Node]) -> ZRPRobot:
    """A ZRP robot file (:meth:`ZRPRobot.to_yaml`), errors at the offending key's line."""
    data = yaml.constructor.SafeConstructor().construct_document(doc.root)
    try:
        robot = ZRPRobot.from_dict(data, source="robot")
    except ValueError as exc:
        detail = str(exc).removeprefix("robot: ")
        raise doc.error(top.get(detail.split(":")[0], doc.root), detail) from None
    if np.abs(robot.b0).max() > MAX_LENGTH_M:
        raise doc.error(top["b0"], f"b0: a length of {np.abs(robot.b0).max():g} m is absurd")
    return robot


# --- all files after a calibration -------------------------------------------------------------
def write_robot_files(
    robot: ZRPRobot, out_dir: str | Path, stem: str = "calibrated_robot",
    base: ArrayLike | None = None, tool: ArrayLike | None = None, nominal: ZRPRobot | None = None,
    frames_in_urdf: bool = False,
) -> dict[str, Path]:
    """Write the arm as URDF, DH and modified-DH table files, ZRP YAML, the base and tool
    transforms, and (a Universal Robots arm) ur_description's kinematics file.

    Files in ``out_dir``:

    - ``<stem>.urdf`` (:func:`to_urdf`): an arm read from a URDF goes into that file (its root
      link, the robot's own base frame), others get a new URDF rooted at ``base_link``; ``base``
      and ``tool`` go in as fixed joints to new links ``world`` and ``tool`` only with
      ``frames_in_urdf`` (else they are in the frames file alone);
    - ``<stem>_dh.yaml``, ``<stem>_mdh.yaml``: standard and modified DH (m and deg; the mismatch
      of :func:`to_dh` and its notes in the header; each file with Hayati rows also says so on
      the console), in the conventions of the nominal table (``nominal``, an arm near
      ``robot``; default: the table or URDF ``robot.source`` was read from, see
      :func:`zrp_ga.model.dh.nominal_tables`) where there is one, so that each row reads as the
      nominal's plus a correction, and then ``<stem>_dh_corrections.csv`` and
      ``<stem>_mdh_corrections.csv`` beside them (:func:`corrections_rows`);
    - ``<stem>.yaml`` (ZRP, :meth:`ZRPRobot.to_yaml`) and ``<stem>_frames.yaml``: ``base`` (the
      pose of the robot's base frame in the instrument's) and ``tool`` (a tool frame in the hand
      frame), identity when not given, each as a 4x4 ``matrix``, ``xyz`` (m) and
      ``quaternion_xyzw`` (x, y, z, w: scalar last);
    - for a Universal Robots arm (:func:`zrp_ga.io.ros_calibration.is_ur`):
      ``<stem>_default_kinematics.yaml``, what ur_description reads
      (:mod:`zrp_ga.io.ros_calibration`).

    The DH, ZRP and UR files hold the arm alone. Returns {"urdf", "dh", "mdh", "zrp", "frames"
    and, where written, "dh_corrections", "mdh_corrections", "ur_kinematics"} -> path.
    """
    return write_all(robot, out_dir, stem, base, tool, nominal, frames_in_urdf)[0]


def write_all(
    robot: ZRPRobot, out_dir: str | Path, stem: str = "calibrated_robot",
    base: ArrayLike | None = None, tool: ArrayLike | None = None, nominal: ZRPRobot | None = None,
    frames_in_urdf: bool = False,
) -> tuple[dict[str, Path], dict[str, DHMismatch]]:
    """:func:`write_robot_files`, and the mismatch of each DH table written ({"dh", "mdh"}):
    each table is computed once (a run of a sweep writes its files in milliseconds)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"urdf": out / f"{stem}.urdf", "dh": out / f"{stem}_dh.yaml", "mdh": out / f"{stem}_mdh.yaml",
             "zrp": out / f"{stem}.yaml", "frames": out / f"{stem}_frames.yaml"}
    full, terms_note = robot, None
    if robot.terms is not None:  # URDF and DH tables carry the geometry only
        terms_note = (f"The calibration's non-geometric terms ({', '.join(robot.terms.spec.names)}) are not in this file: it holds "
                      f"the geometric part; {paths['zrp'].name} (ZRP YAML) carries them")  # fmt: skip
        log.info("URDF and DH files hold the geometric part of %s; its terms (%s) are in %s only", robot.name,
                 ", ".join(robot.terms.spec.names), paths["zrp"].name)  # fmt: skip
        robot = robot.geometric
    urdf = to_urdf(robot, None, *((base, tool) if frames_in_urdf else (None, None)))
    if terms_note is not None:
        lines = urdf.split("\n", 1)
        first = lines[0].startswith("<?xml")
        comment = f"<!-- {terms_note.replace('--', '-')} -->"
        urdf = f"{lines[0]}\n{comment}\n{lines[1] if len(lines) > 1 else ''}" if first else f"{comment}\n{urdf}"
    paths["urdf"].write_text(urdf)
    like = nominal_tables(nominal) if nominal is not None else _source_tables(robot.source)
    if like is not None and like["dh"].joint_types != robot.joint_types:
        like = None  # a source of another arm: the tables' own rules
    mismatches = tables(robot, like=like)  # to_dh(robot, convention, like=...) of each
    for convention, title in (("dh", "Standard DH"), ("mdh", "Modified DH")):
        table, mismatch = mismatches[convention]
        header = [f"{title} table of {robot.name} (zrp_ga.io.robot_files.to_dh): {mismatch}", *mismatch.notes,
                  *([terms_note] if terms_note else [])]  # fmt: skip
        if like is not None:
            paths[f"{convention}_corrections"] = out / f"{stem}_{convention}_corrections.csv"
            header.append(f"In the nominal table's conventions (row = nominal + correction; {paths[f'{convention}_corrections'].name})")
            write_csv(paths[f"{convention}_corrections"], corrections_rows(table, like[convention]))
        dh_to_yaml(table, paths[convention], comment="\n".join(header), near=None if like is None else like[convention])
        if table.betas.any():
            rows = ", ".join(str(i + 1) for i in np.flatnonzero(table.betas))
            to_log_files(log, logging.INFO, [f"{paths[convention].name}: row(s) {rows} use Hayati's parameterisation (nearly "
                                             "parallel axes; the file's notes say why)"])  # a note on a file: the log, not the console
    paths["zrp"].write_text(_yaml_text(full.to_dict()))  # full.to_yaml(path), the same text: the terms included
    poses = {"base": base, "tool": tool}
    frames = {k: _identity_entry() if T is None else _frame_entry(check_transform(T, k)) for k, T in poses.items()}
    comment = (
        "# base: pose of the robot's base frame (the URDF's root link) in the instrument's frame;\n"
        "# tool: pose of the tool frame in the hand frame (the URDF's tip link). Lengths m;\n"
        "# quaternion_xyzw: x, y, z, w (scalar last, as scipy and ROS).\n"
    )
    paths["frames"].write_text(comment + _yaml_text(frames))
    if ros_calibration.is_ur(robot):
        paths["ur_kinematics"] = out / f"{stem}_default_kinematics.yaml"
        ros_calibration.write_ur_kinematics(robot, paths["ur_kinematics"], None if like is None else like["dh"],
                                            _ur_world(robot.source), table=mismatches["dh"][0])  # fmt: skip
    return paths, {k: m for k, (_, m) in mismatches.items()}


@functools.lru_cache(maxsize=16)
def _source_tables(source: object) -> dict[str, DHTable] | None:
    """The nominal tables of an arm read from ``source`` (:func:`zrp_ga.model.dh.nominal_tables`):
    a DH table's own and the other convention's, a URDF's arm's; None for other sources (the
    runs of a sweep share their nominal arm's source: computed once)."""
    if isinstance(source, DHTable):
        other = "mdh" if source.convention == "dh" else "dh"
        return {source.convention: source, other: to_dh(source.to_robot(), other, samples=1)[0]}
    if isinstance(source, URDFSource):
        return nominal_tables(read_urdf(source.path, source.text, source.base_link, source.tip_link))
    return None


def _ur_world(source: object) -> str:
    """The world frame of a UR arm (:func:`zrp_ga.io.ros_calibration.ur_kinematics`): ROS's
    ``base_link`` for an arm read from a URDF from a link other than ``base_link_inertia`` or
    ``base`` (ur_description's URDF from its root), else the controller's ``base`` (UR's DH)."""
    if isinstance(source, URDFSource) and not source.base_link.endswith(("base_link_inertia", "base")):
        return "base_link"
    return "base"


CORRECTION_COLUMNS = ["row", "joint", "parameter", "unit", "nominal", "calibrated", "correction"]


def corrections_rows(table: DHTable, nominal: DHTable) -> list[dict]:
    """The table of corrections beside a DH file: one row per parameter (columns
    :data:`CORRECTION_COLUMNS`), mm and deg: each joint row's ``a, alpha, d, theta`` (and
    ``beta`` where either table has one), then ``base`` and ``tool``: ``x, y, z``, ``roll,
    pitch, yaw`` (the triple nearest the nominal's) and ``turn``, the angle of the rotation
    that takes the nominal frame onto the calibrated one (:func:`zrp_ga.model.dh.corrections`).

    >>> from zrp_ga.io import presets
    >>> t = presets.get("ur10").source
    >>> corrections_rows(t, t)[1]
    {'row': 1, 'joint': 'shoulder_pan_joint', 'parameter': 'alpha', 'unit': 'deg', 'nominal': 90.0, 'calibrated': 90.0, 'correction': 0.0}
    """
    change = dh_corrections(table, nominal)
    names = table.joint_names or tuple(f"joint_{i + 1}" for i in range(table.n))
    scale = {"a": (1e3, "mm"), "d": (1e3, "mm"), "alpha": (180 / np.pi, "deg"), "theta": (180 / np.pi, "deg"),
             "beta": (180 / np.pi, "deg")}  # fmt: skip
    rows = []
    for i in range(table.n):
        for kind in ("a", "alpha", "d", "theta", "beta"):
            if kind == "beta" and not (table.betas[i] or nominal.betas[i]):
                continue
            f, unit = scale[kind]
            c = change[kind][i] * f
            rows.append({"row": i + 1, "joint": names[i], "parameter": kind, "unit": unit,
                         "nominal": float(getattr(nominal, kind)[i] * f), "calibrated": float(getattr(nominal, kind)[i] * f + c),
                         "correction": float(c)})  # fmt: skip
    for key in ("base", "tool"):
        T, N = getattr(table, key), getattr(nominal, key)
        near = so3.rpy(N[:3, :3])
        values = [*(N[:3, 3] * 1e3), *np.degrees(near)], [*(T[:3, 3] * 1e3), *np.degrees(rpy_near(T[:3, :3], near))]
        for k, name in enumerate(("x", "y", "z", "roll", "pitch", "yaw")):
            rows.append({"row": key, "joint": "", "parameter": name, "unit": "mm" if k < 3 else "deg",
                         "nominal": float(values[0][k]), "calibrated": float(values[1][k]),
                         "correction": float(values[1][k] - values[0][k])})  # fmt: skip
        turn = float(np.degrees(np.linalg.norm(change[f"{key}_rotvec"])))
        rows.append({"row": key, "joint": "", "parameter": "turn", "unit": "deg", "nominal": 0.0, "calibrated": turn, "correction": turn})
    return rows


@functools.cache
def _identity_entry() -> dict:
    """``_frame_entry(np.eye(4))``, computed once (only written: not to be changed)."""
    return _frame_entry(np.eye(4))


def _frame_entry(T: Array) -> dict:
    xyzw = Rotation.from_matrix(T[:3, :3]).as_quat()
    return {"matrix": T.tolist(), "xyz": T[:3, 3].tolist(), "quaternion_xyzw": xyzw.tolist()}
