#!/usr/bin/env python3
"""Expand the LBR iiwa description of lbr-stack/lbr_fri_ros2_stack
(kinematic chain only) into a URDF.

Follows lbr_description/urdf/MODEL/MODEL.xacro as `xacro MODEL.xacro` expands
it with its default `robot_name:=lbr`: the `lbr_floating_link`, the fixed
`lbr_floating_joint` to `lbr_link_0`, then every <joint> of
urdf/MODEL/MODEL_description.xacro as written there (origin, axis, parent,
child) with the <limit> of urdf/MODEL/joint_limits.yaml (degrees, turned into
radians by the xacro's `value * PI / 180` with its PI = 3.1415926535897931).
Links carry no visuals or inertia.

    scripts/lbr_urdf.py DESCRIPTION_DIR MODEL COMMIT > MODEL.urdf

DESCRIPTION_DIR is a checkout of lbr_description at COMMIT (only written into
the header).
"""

import sys
import xml.etree.ElementTree as ET

import yaml

PI = 3.1415926535897931


def main():
    root, model, commit = sys.argv[1:4]
    rn = "lbr"
    desc = f"urdf/{model}/{model}_description.xacro"
    lims = yaml.safe_load(open(f"{root}/urdf/{model}/joint_limits.yaml"))
    ns = {"xacro": "http://www.ros.org/wiki/xacro"}
    macro = ET.parse(f"{root}/{desc}").getroot().find("xacro:macro", ns)
    sub = lambda s: s.replace("${robot_name}", rn)  # noqa: E731
    joints = macro.findall("joint")
    links = [sub(j.find("child").get("link")) for j in joints]
    out = [
        '<?xml version="1.0"?>',
        f"<!-- Kinematics of the KUKA LBR {model} from lbr-stack/lbr_fri_ros2_stack,",
        f"     commit {commit}: lbr_description/{desc} (joints)",
        f"     and lbr_description/urdf/{model}/joint_limits.yaml (limits, degrees to radians",
        f"     as the xacro does), expanded as `xacro {model}.xacro` does with its default",
        "     robot_name:=lbr (scripts/lbr_urdf.py). Links without visuals or inertia.",
        "     KUKA publishes no ROS description of its own; this stack's limits are",
        "     KUKA's datasheet values. -->",
        f'<robot name="{model}">',
        f'  <link name="{rn}_floating_link"/>',
        f'  <link name="{rn}_link_0"/>',
    ]
    out += [f'  <link name="{link}"/>' for link in links]
    out.append(
        f'  <joint name="{rn}_floating_joint" type="fixed"><parent link="{rn}_floating_link"/>'
        f'<child link="{rn}_link_0"/></joint>'
    )
    for j in joints:
        name = sub(j.get("name"))
        o = j.find("origin")
        body = (
            f'<origin rpy="{o.get("rpy")}" xyz="{o.get("xyz")}"/>'
            f'<parent link="{sub(j.find("parent").get("link"))}"/>'
            f'<child link="{sub(j.find("child").get("link"))}"/>'
        )
        if j.get("type") == "revolute":
            key = name.removeprefix(f"{rn}_")
            lim = lims[key]
            deg = lambda v: repr(v * PI / 180)  # noqa: E731
            body += (
                f'<axis xyz="{j.find("axis").get("xyz")}"/>'
                f'<limit effort="{lim["effort"]}" lower="{deg(lim["lower"])}" '
                f'upper="{deg(lim["upper"])}" velocity="{deg(lim["velocity"])}"/>'
            )
        out.append(f'  <joint name="{name}" type="{j.get("type")}">{body}</joint>')
    out.append("</robot>")
    print("\n".join(out))


if __name__ == "__main__":
    main()
