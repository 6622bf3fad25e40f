#!/usr/bin/env python3
"""Expand Franka's description (arm kinematics only) into a URDF.

Follows robots/common/franka_arm.xacro of frankaemika/franka_description
(the `base` link, the fixed joint to `<arm_id>_link0`, joints 1..7 about z
and the fixed joint8 to `<arm_id>_link8`, the flange), with the numbers of
robots/<arm_id>/kinematics.yaml and joint_limits.yaml, the way
`xacro <arm_id>.urdf.xacro hand:=false` does with the default (empty)
arm_prefix (names `<arm_id>_joint1`, ...). No visuals or inertia.

    scripts/franka_urdf.py DESCRIPTION_DIR ARM_ID COMMIT > fr3.urdf
"""

import sys

import yaml


def num(v):
    return repr(float(v))


def main():
    root, arm, commit = sys.argv[1:4]
    kin = yaml.safe_load(open(f"{root}/robots/{arm}/kinematics.yaml"))
    lim = yaml.safe_load(open(f"{root}/robots/{arm}/joint_limits.yaml"))
    p = f"{arm}_"
    out = [
        '<?xml version="1.0"?>',
        "<!-- Kinematics of frankaemika/franka_description",
        f"     commit {commit} (2025-03-21), arm_id {arm}:",
        f"     robots/{arm}/kinematics.yaml and robots/{arm}/joint_limits.yaml",
        "     expanded as robots/common/franka_arm.xacro does (scripts/franka_urdf.py).",
        "     Links without visuals or inertia. -->",
        f'<robot name="{arm}">',
        '  <link name="base"/>',
    ]
    out += [f'  <link name="{p}link{i}"/>' for i in range(9)]

    def origin(k):
        return (f'<origin rpy="{num(k["roll"])} {num(k["pitch"])} {num(k["yaw"])}" '
                f'xyz="{num(k["x"])} {num(k["y"])} {num(k["z"])}"/>')

    out.append(f'  <joint name="{p}base_joint" type="fixed"><parent link="base"/>'
               f'<child link="{p}link0"/><origin rpy="0 0 0" xyz="0 0 0"/></joint>')
    for i in range(1, 8):
        k = kin[f"joint{i}"]["kinematic"]
        m = lim[f"joint{i}"]["limit"]
        out.append(
            f'  <joint name="{p}joint{i}" type="revolute">{origin(k)}<parent link="{p}link{i - 1}"/>'
            f'<child link="{p}link{i}"/><axis xyz="0 0 1"/><limit lower="{num(m["lower"])}" '
            f'upper="{num(m["upper"])}" effort="{num(m["effort"])}" velocity="{num(m["velocity"])}"/></joint>'
        )
    k = kin["joint8"]["kinematic"]
    out.append(f'  <joint name="{p}joint8" type="fixed">{origin(k)}<parent link="{p}link7"/>'
               f'<child link="{p}link8"/></joint>')
    out.append("</robot>")
    print("\n".join(out))


if __name__ == "__main__":
    main()
