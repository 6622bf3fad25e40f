#!/usr/bin/env python3
"""An independent reader of Universal Robots' kinematics YAML.

Reads the file with PyYAML's safe loader (what xacro's `load_yaml` uses) and
builds the chain the way urdf/ur_macro.xacro of
UniversalRobots/Universal_Robots_ROS2_Description (2.4.5, commit 2221ec0f)
builds it from that file: `base_link`; `base_link_inertia` and `base` each
at rpy (0, 0, π) from it; the six revolute joints `shoulder_pan_joint` …
`wrist_3_joint`, each an <origin> (xyz, then rpy: R = Rz(yaw)·Ry(pitch)·Rx(roll))
taken from the file's `shoulder` … `wrist_3` entries, then a rotation about z;
`flange` at rpy (0, −π/2, −π/2) from `wrist_3_link`; `tool0` at rpy
(π/2, 0, π/2) from `flange`. Nothing of robimu is used.

    python3 tests/ur_kinematics_fk.py fk FILE.yaml POSES.csv [TOL]
        POSES.csv: rows of q1..q6, then tool0's position in `base` (3) and
        its rotation matrix row by row (9). Prints the worst differences;
        exits 1 past TOL (default 1e-9 m / 1e-9 rad).
    python3 tests/ur_kinematics_fk.py same A.yaml B.yaml
        Exits 1 unless both files hold the same numbers and hash.

Needs numpy and PyYAML.
"""

import csv
import math
import sys

import numpy as np
import yaml

LINKS = ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"]
KEYS = ["x", "y", "z", "roll", "pitch", "yaw"]


def rot(axis, t):
    c, s = math.cos(t), math.sin(t)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def origin(xyz, rpy):
    t = np.eye(4)
    t[:3, :3] = rot("z", rpy[2]) @ rot("y", rpy[1]) @ rot("x", rpy[0])
    t[:3, 3] = xyz
    return t


def joint(q):
    t = np.eye(4)
    t[:3, :3] = rot("z", q)
    return t


def load(path):
    with open(path) as f:
        kin = yaml.safe_load(f)["kinematics"]
    for link in LINKS:
        for k in KEYS:
            v = kin[link][k]
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise SystemExit(f"{path}: kinematics.{link}.{k} = {v!r} is not a YAML number")
    if not isinstance(kin["hash"], str):
        raise SystemExit(f"{path}: kinematics.hash is not a string")
    return kin


def tool0_in_base(kin, q):
    pi = math.pi
    base = origin([0, 0, 0], [0, 0, pi])  # base_link -> base
    t = origin([0, 0, 0], [0, 0, pi])  # base_link -> base_link_inertia
    for link, qi in zip(LINKS, q):
        k = kin[link]
        t = t @ origin([k["x"], k["y"], k["z"]], [k["roll"], k["pitch"], k["yaw"]]) @ joint(qi)
    t = t @ origin([0, 0, 0], [0, -pi / 2.0, -pi / 2.0])  # wrist_3_link -> flange
    t = t @ origin([0, 0, 0], [pi / 2.0, 0, pi / 2.0])  # flange -> tool0
    return np.linalg.inv(base) @ t


def fk(path, poses, tol):
    kin = load(path)
    dp = dr = 0.0
    n = 0
    with open(poses) as f:
        for row in csv.reader(f):
            if not row or row[0].startswith("#"):
                continue
            v = [float(x) for x in row]
            q, p, r = v[:6], np.array(v[6:9]), np.array(v[9:18]).reshape(3, 3)
            t = tool0_in_base(kin, q)
            dp = max(dp, float(np.abs(t[:3, 3] - p).max()))
            m = t[:3, :3].T @ r
            w = [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]
            dr = max(dr, math.atan2(np.linalg.norm(w), np.trace(m) - 1))
            n += 1
    ok = n > 0 and dp <= tol and dr <= tol
    print(f"{path}: {n} configurations, worst |Δp| {dp:.2e} m, |Δθ| {dr:.2e} rad "
          f"(hash {kin['hash']}) {'ok' if ok else 'FAIL'}")
    return ok


def same(a, b):
    ka, kb = load(a), load(b)
    diffs = [f"{link}.{k}: {ka[link][k]!r} != {kb[link][k]!r}"
             for link in LINKS for k in KEYS if float(ka[link][k]) != float(kb[link][k])]
    if ka["hash"] != kb["hash"]:
        diffs.append(f"hash: {ka['hash']} != {kb['hash']}")
    print(f"{a} vs {b}: {36 - len(diffs)} of 36 numbers equal, hash "
          f"{'equal' if ka['hash'] == kb['hash'] else 'differs'} {'ok' if not diffs else 'FAIL'}")
    for d in diffs:
        print(f"  {d}")
    return not diffs


def main():
    if len(sys.argv) >= 4 and sys.argv[1] == "fk":
        tol = float(sys.argv[4]) if len(sys.argv) > 4 else 1e-9
        sys.exit(0 if fk(sys.argv[2], sys.argv[3], tol) else 1)
    if len(sys.argv) == 4 and sys.argv[1] == "same":
        sys.exit(0 if same(sys.argv[2], sys.argv[3]) else 1)
    raise SystemExit(__doc__)


if __name__ == "__main__":
    main()
