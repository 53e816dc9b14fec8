"""ur_description's reading of a default_kinematics.yaml, written for the tests (and
experiments/robot_exports.py) only.

ur_description (Universal_Robots_ROS2_Description, ``urdf/ur_macro.xacro`` and
``urdf/inc/ur_common.xacro``) loads the file with ``xacro.load_yaml`` and builds the arm as:
``base_link`` -> ``base_link_inertia`` (fixed, rpy ``0 0 pi``) -> six revolute joints, each with
``origin xyz = (X.x, X.y, X.z)``, ``rpy = (X.roll, X.pitch, X.yaw)`` and ``axis 0 0 1`` for X =
shoulder, upper_arm, forearm, wrist_1, wrist_2, wrist_3 -> ``wrist_3_link`` -> ``flange`` (fixed,
rpy ``0 -pi/2 -pi/2``) -> ``tool0`` (fixed, rpy ``pi/2 0 pi/2``). The xacro below is written
here to that description (meshes, inertias and limits left out); the ``xacro`` package expands
it with the file and yourdfpy loads the URDF (its forward kinematics: ``get_transform``).
"""

from pathlib import Path

SECTIONS = [("shoulder_pan_joint", "base_link_inertia", "shoulder_link", "shoulder"),
            ("shoulder_lift_joint", "shoulder_link", "upper_arm_link", "upper_arm"),
            ("elbow_joint", "upper_arm_link", "forearm_link", "forearm"),
            ("wrist_1_joint", "forearm_link", "wrist_1_link", "wrist_1"),
            ("wrist_2_joint", "wrist_1_link", "wrist_2_link", "wrist_2"),
            ("wrist_3_joint", "wrist_2_link", "wrist_3_link", "wrist_3")]  # fmt: skip
LINKS = ["base_link", "base_link_inertia", *[s[2] for s in SECTIONS], "flange", "tool0"]


def ur_xacro() -> str:
    """The kinematic chain of ur_description's ur_macro.xacro (module docstring), in xacro."""
    joints = "\n".join(
        f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f"<origin xyz=\"${{k['{s}']['x']}} ${{k['{s}']['y']}} ${{k['{s}']['z']}}\" "
        f"rpy=\"${{k['{s}']['roll']}} ${{k['{s}']['pitch']}} ${{k['{s}']['yaw']}}\"/>"
        '<axis xyz="0 0 1"/><limit lower="-6.2832" upper="6.2832" effort="1" velocity="1"/></joint>'
        for name, parent, child, s in SECTIONS
    )
    return f"""<?xml version="1.0"?>
<robot xmlns:xacro="http://wiki.ros.org/xacro" name="ur">
  <xacro:arg name="kinematics_params" default=""/>
  <xacro:property name="config" value="${{xacro.load_yaml('$(arg kinematics_params)')}}"/>
  <xacro:property name="k" value="${{config['kinematics']}}"/>
  <xacro:property name="kinematics_hash" value="${{k['hash']}}"/>
{chr(10).join(f'  <link name="{link}"/>' for link in LINKS)}
  <joint name="base_link-base_link_inertia" type="fixed"><parent link="base_link"/><child link="base_link_inertia"/>
    <origin xyz="0 0 0" rpy="0 0 ${{pi}}"/></joint>
{joints}
  <joint name="wrist_3-flange" type="fixed"><parent link="wrist_3_link"/><child link="flange"/>
    <origin xyz="0 0 0" rpy="0 ${{-pi/2.0}} ${{-pi/2.0}}"/></joint>
  <joint name="flange-tool0" type="fixed"><parent link="flange"/><child link="tool0"/>
    <origin xyz="0 0 0" rpy="${{pi/2.0}} 0 ${{pi/2.0}}"/></joint>
</robot>
"""


def ur_description_urdf(tmp_path: Path, kinematics_file: Path):
    """yourdfpy's URDF of the xacro expanded (by the xacro package) with ``kinematics_file``."""
    import xacro
    import yourdfpy

    source = tmp_path / "ur.urdf.xacro"
    source.write_text(ur_xacro())
    doc = xacro.process_file(str(source), mappings={"kinematics_params": str(kinematics_file)})
    out = tmp_path / "ur_expanded.urdf"
    out.write_text(doc.toprettyxml(indent="  "))
    return yourdfpy.URDF.load(str(out), build_scene_graph=True, load_meshes=False, build_collision_scene_graph=False)
