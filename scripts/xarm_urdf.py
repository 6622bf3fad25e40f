#!/usr/bin/env python3
"""Expand UFactory's xArm description (kinematic chain only) into a URDF.

Follows xarm_description of xArm-Developer/xarm_ros2 as
`xacro xarm_device.urdf.xacro dof:=N` expands it with its defaults
(`limited:=false`, empty prefix, `attach_to:=world`): the `world` link, the
fixed `world_joint` to `link_base`, joints `joint1`..`jointN` whose
<origin> is config/kinematics/default/xarmN_default_kinematics.yaml
(common.link.xacro's `common_joint_origin`), whose <axis> and <limit> are
urdf/xarmN/xarmN.urdf.xacro's (the macro's default position limits, the
`${...}` expressions evaluated as xacro does), and the fixed `joint_eef`
(identity) to `link_eef`, from xarm_device_macro.xacro. Links carry no
visuals or inertia.

    scripts/xarm_urdf.py DESCRIPTION_DIR N BRANCH COMMIT > xarmN.urdf

DESCRIPTION_DIR is a checkout of xarm_description at COMMIT (BRANCH and
COMMIT are only written into the header).
"""

import math
import re
import sys
import xml.etree.ElementTree as ET

import yaml


def num(v):
    return repr(float(v))


def xacro_eval(expr, params):
    """A `${...}` expression of the macro (numbers, pi, + - * /)."""
    m = re.fullmatch(r"\$\{(.*)\}", expr.strip())
    if m is None:
        return float(expr)
    return eval(m.group(1), {"__builtins__": {}}, {"pi": math.pi, **params})


def main():
    root, n, branch, commit = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
    name = f"xarm{n}"
    kin_file = f"config/kinematics/default/{name}_default_kinematics.yaml"
    xacro_file = f"urdf/{name}/{name}.urdf.xacro"
    kin = yaml.safe_load(open(f"{root}/{kin_file}"))["kinematics"]
    text = open(f"{root}/{xacro_file}").read()
    # The macro's parameter defaults: `jointK_lower_limit:=${...}`.
    params = {}
    for key, expr in re.findall(r"(joint\d_(?:lower|upper)_limit):=(\$\{[^}]*\})", text):
        params[key] = xacro_eval(expr, {})
    ns = {"xacro": "http://ros.org/wiki/xacro"}
    macro = ET.fromstring(text).find("xacro:macro", ns)
    out = [
        '<?xml version="1.0"?>',
        f"<!-- Kinematics of the UFactory xArm {n} from xArm-Developer/xarm_ros2,",
        f"     branch {branch}, commit {commit}: xarm_description/{kin_file}",
        f"     (joint origins) and xarm_description/{xacro_file} (axes, position limits",
        "     of the macro's defaults, i.e. limited:=false, and velocity limits), with",
        "     link_base, link_eef and the fixed joints of urdf/xarm_device_macro.xacro,",
        f"     expanded as `xacro xarm_device.urdf.xacro dof:={n}` does with its defaults",
        "     (scripts/xarm_urdf.py). Links without visuals or inertia. -->",
        f'<robot name="{name}">',
        '  <link name="world"/>',
        '  <link name="link_base"/>',
    ]
    out += [f'  <link name="link{i}"/>' for i in range(1, n + 1)]
    out.append('  <link name="link_eef"/>')
    out.append(
        '  <joint name="world_joint" type="fixed"><parent link="world"/><child link="link_base"/>'
        '<origin xyz="0 0 0" rpy="0 0 0"/></joint>'
    )
    for j in macro.findall("joint"):
        jn = j.get("name").replace("${prefix}", "")
        k = kin[jn]
        parent = j.find("parent").get("link").replace("${prefix}", "")
        child = j.find("child").get("link").replace("${prefix}", "")
        axis = j.find("axis").get("xyz")
        lim = j.find("limit")
        lo = xacro_eval(lim.get("lower"), params)
        hi = xacro_eval(lim.get("upper"), params)
        out.append(
            f'  <joint name="{jn}" type="{j.get("type")}">'
            f'<origin xyz="{num(k["x"])} {num(k["y"])} {num(k["z"])}" '
            f'rpy="{num(k["roll"])} {num(k["pitch"])} {num(k["yaw"])}"/>'
            f'<parent link="{parent}"/><child link="{child}"/><axis xyz="{axis}"/>'
            f'<limit lower="{num(lo)}" upper="{num(hi)}" effort="{lim.get("effort")}" '
            f'velocity="{lim.get("velocity")}"/></joint>'
        )
    out.append(
        f'  <joint name="joint_eef" type="fixed"><origin xyz="0 0 0" rpy="0 0 0"/>'
        f'<parent link="link{n}"/><child link="link_eef"/></joint>'
    )
    out.append("</robot>")
    print("\n".join(out))


if __name__ == "__main__":
    main()
