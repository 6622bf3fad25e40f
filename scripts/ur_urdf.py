#!/usr/bin/env python3
"""Expand Universal Robots' description (kinematic chain only) into a URDF.

Follows urdf/ur_macro.xacro of UniversalRobots/Universal_Robots_ROS2_Description
(the joints from `base_link` to `tool0`, plus the `base` frame), with the
numbers of config/<model>/default_kinematics.yaml and joint_limits.yaml, the
way `xacro ur.urdf.xacro ur_type:=<model>` does (`!degrees` values in
radians). Links carry no visuals or inertia: this is the kinematics the
catalogue test compares against.

    scripts/ur_urdf.py DESCRIPTION_DIR MODEL COMMIT > ur5e.urdf

DESCRIPTION_DIR holds config/<model>/*.yaml (a checkout of the repository at
COMMIT, which is only written into the header).
"""

import math
import sys

import yaml


def degrees(loader, node):
    return math.radians(float(loader.construct_scalar(node)))


yaml.SafeLoader.add_constructor("!degrees", degrees)

JOINTS = [
    ("shoulder_pan_joint", "base_link_inertia", "shoulder_link", "shoulder"),
    ("shoulder_lift_joint", "shoulder_link", "upper_arm_link", "upper_arm"),
    ("elbow_joint", "upper_arm_link", "forearm_link", "forearm"),
    ("wrist_1_joint", "forearm_link", "wrist_1_link", "wrist_1"),
    ("wrist_2_joint", "wrist_1_link", "wrist_2_link", "wrist_2"),
    ("wrist_3_joint", "wrist_2_link", "wrist_3_link", "wrist_3"),
]


def num(v):
    return repr(float(v))


def main():
    root, model, commit = sys.argv[1:4]
    kin = yaml.safe_load(open(f"{root}/config/{model}/default_kinematics.yaml"))["kinematics"]
    lim = yaml.safe_load(open(f"{root}/config/{model}/joint_limits.yaml"))["joint_limits"]
    pi = math.pi
    out = [
        '<?xml version="1.0"?>',
        "<!-- Kinematics of UniversalRobots/Universal_Robots_ROS2_Description",
        f"     commit {commit} (release 2.4.5), ur_type:={model}:",
        f"     config/{model}/default_kinematics.yaml (hash {kin['hash']}) and",
        f"     config/{model}/joint_limits.yaml expanded as urdf/ur_macro.xacro does",
        "     (scripts/ur_urdf.py). Links without visuals or inertia. -->",
        f'<robot name="{model}">',
    ]
    links = ["base_link", "base_link_inertia", "base", "flange", "tool0"] + [j[2] for j in JOINTS]
    out += [f'  <link name="{n}"/>' for n in links]

    def fixed(name, parent, child, rpy):
        out.append(
            f'  <joint name="{name}" type="fixed"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="0 0 0" rpy="{" ".join(num(v) for v in rpy)}"/></joint>'
        )

    fixed("base_link-base_link_inertia", "base_link", "base_link_inertia", [0, 0, pi])
    for name, parent, child, key in JOINTS:
        k = kin[key]
        lj = lim[name]
        xyz = " ".join(num(k[c]) for c in "xyz")
        rpy = " ".join(num(k[c]) for c in ("roll", "pitch", "yaw"))
        kind = "revolute" if lj.get("has_position_limits", True) else "continuous"
        limit = f'effort="{num(lj["max_effort"])}" velocity="{num(lj["max_velocity"])}"'
        if kind == "revolute":
            limit = f'lower="{num(lj["min_position"])}" upper="{num(lj["max_position"])}" ' + limit
        out.append(
            f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/><limit {limit}/></joint>'
        )
    fixed("wrist_3-flange", "wrist_3_link", "flange", [0, -pi / 2.0, -pi / 2.0])
    fixed("flange-tool0", "flange", "tool0", [pi / 2.0, 0, pi / 2.0])
    fixed("base_link-base_fixed_joint", "base_link", "base", [0, 0, pi])
    out.append("</robot>")
    print("\n".join(out))


if __name__ == "__main__":
    main()
