#!/usr/bin/env python3
"""Check robimu's built-in robots against their makers' URDFs, independently.

For each built-in description host/model/robots/NAME.toml this reads the
maker's URDF tests/fixtures/makers/NAME.urdf (its header names the maker's
repository, file and commit) with its own numpy forward kinematics of the URDF
XML (every link's pose from the root through the joints' <origin> and
rotations about <axis>), and the robimu description with its own reading of
the TOML format (host/model/src/robot.rs: base_to_model, then per joint
Rz(q+θ0)·Tz(d)·Tx(a)·Rx(α)·C_i). It compares the pose of the maker's flange
frame in the maker's base frame ([frames] base, flange) at 200 random
configurations within the joint limits, and the joint names and limits.

    python3 tests/makers_fk.py [ROOT] [NAME...]

With `--written NAME FILE [ROOT]` it checks instead a URDF that robimu wrote
for the built-in NAME (`robimu robots show NAME --urdf FILE`) against the
maker's: both read by the same independent reader, the flange frame
([frames] flange) in the base frame ([frames] base) at 200 random
configurations, and the joint names and limits.

With `--poses FILE.urdf BASE FLANGE POSES.csv [TOL]` it reads any URDF
(e.g. one `robimu export --format urdf` wrote) and compares the pose of
FLANGE in BASE with each row of POSES.csv: the angles of the chain's
revolute joints in order, then the position (3) and the rotation matrix row
by row (9); `#` lines are comments.

Prints one line per robot with the worst errors; exits 1 if any exceeds
1e-6 m / 1e-6 rad. Needs numpy; Python >= 3.11 (tomllib).
"""

import math
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

TOL = 1e-6
SAMPLES = 200


def rot(axis, t):
    axis = np.asarray(axis, float)
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * k @ k


def hom(r=np.eye(3), p=(0, 0, 0)):
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = p
    return t


def rpy_xyz(xyz, rpy):
    r, p, y = rpy
    return hom(rot([0, 0, 1], y) @ rot([0, 1, 0], p) @ rot([1, 0, 0], r), xyz)


class Urdf:
    def __init__(self, path):
        root = ET.parse(path).getroot()
        self.joints = {}
        for j in root.findall("joint"):
            o = j.find("origin")
            xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
            rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
            a = j.find("axis")
            axis = [float(v) for v in a.get("xyz").split()] if a is not None else [1, 0, 0]
            lim = j.find("limit")
            self.joints[j.find("child").get("link")] = dict(
                name=j.get("name"),
                kind=j.get("type"),
                parent=j.find("parent").get("link"),
                origin=rpy_xyz(xyz, rpy),
                axis=axis,
                limit=None if lim is None else lim.attrib,
            )

    def path(self, link):
        """Joints from the root to `link`."""
        out = []
        while link in self.joints:
            out.append(self.joints[link])
            link = self.joints[link]["parent"]
        return out[::-1]

    def pose(self, link, q):
        """Pose of `link` in the root link; q: joint name -> angle."""
        t = np.eye(4)
        for j in self.path(link):
            t = t @ j["origin"]
            if j["kind"] in ("revolute", "continuous"):
                t = t @ hom(rot(j["axis"], q[j["name"]]))
        return t

    def flange(self, base, flange, q):
        return np.linalg.inv(self.pose(base, q)) @ self.pose(flange, q)


def model_pose(desc, q):
    f = desc["frames"]["base_to_model"]
    t = rpy_xyz(f["xyz"], f["rpy"])
    for j, qi in zip(desc["joint"], q):
        t = t @ hom(rot([0, 0, 1], qi + j["theta0"]), [0, 0, j["d"]])
        t = t @ hom(np.eye(3), [j["a"], 0, 0]) @ hom(rot([1, 0, 0], j["alpha"]))
        o = j.get("origin")
        if o is not None:
            t = t @ rpy_xyz(o["xyz"], o["rpy"])
    return t


def check(root, name, rng):
    desc = tomllib.loads((root / f"host/model/robots/{name}.toml").read_text())
    fixture = root / f"tests/fixtures/makers/{name}.urdf"
    urdf = Urdf(fixture)
    header = fixture.read_text().split("-->")[0].split("<!--")[1].split()
    names = desc["joint_names"]
    base, flange = desc["frames"]["base"], desc["frames"]["flange"]
    chain = [j["name"] for j in urdf.path(flange) if j["kind"] in ("revolute", "continuous")]
    problems = []
    if chain != names:
        problems.append(f"joint names {names} != URDF chain {chain}")
    by_name = {j["name"]: j for j in urdf.joints.values()}
    for jn, jd in zip(names, desc["joint"]):
        lim = by_name[jn]["limit"] or {}
        lo = float(lim.get("lower", -math.pi)) if by_name[jn]["kind"] == "revolute" else -math.pi
        hi = float(lim.get("upper", math.pi)) if by_name[jn]["kind"] == "revolute" else math.pi
        if abs(lo - jd["q_min"]) > 1e-12 or abs(hi - jd["q_max"]) > 1e-12:
            problems.append(f"{jn}: position limits {jd['q_min']}..{jd['q_max']} != URDF {lo}..{hi}")
        if abs(float(lim.get("velocity", "nan")) - jd["qd_max"]) > 1e-12:
            problems.append(f"{jn}: velocity limit {jd['qd_max']} != URDF {lim.get('velocity')}")
    dp = dr = 0.0
    for _ in range(SAMPLES):
        q = [rng.uniform(j["q_min"], j["q_max"]) for j in desc["joint"]]
        a = model_pose(desc, q)
        b = urdf.flange(base, flange, dict(zip(names, q)))
        dp = max(dp, float(np.abs(a[:3, 3] - b[:3, 3]).max()))
        m = a[:3, :3].T @ b[:3, :3]
        w = [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]
        dr = max(dr, math.atan2(np.linalg.norm(w), np.trace(m) - 1))
    ok = dp <= TOL and dr <= TOL and not problems
    src = " ".join(header[:8])
    print(f"{name:8} {base}->{flange}: {SAMPLES} configurations, worst |Δp| {dp:.2e} m, "
          f"|Δθ| {dr:.2e} rad vs {fixture.relative_to(root)} ({src}) {'ok' if ok else 'FAIL'}")
    for p in problems:
        print(f"  {p}")
    return ok


def check_written(root, name, written, rng):
    desc = tomllib.loads((root / f"host/model/robots/{name}.toml").read_text())
    fixture = root / f"tests/fixtures/makers/{name}.urdf"
    maker, ours = Urdf(fixture), Urdf(written)
    base, flange = desc["frames"]["base"], desc["frames"]["flange"]
    names = desc["joint_names"]
    problems = []
    revolute = [j["name"] for j in ours.path(flange) if j["kind"] in ("revolute", "continuous")]
    if revolute != names:
        problems.append(f"joint names {revolute} != {names}")
    if base not in [j["parent"] for j in ours.path(flange)]:
        problems.append(f"the base frame {base} is not on the path to {flange}")
    mj = {j["name"]: j for j in maker.joints.values()}
    oj = {j["name"]: j for j in ours.joints.values()}
    for jn in names:
        ml, ol = mj[jn]["limit"] or {}, oj[jn]["limit"] or {}
        for key in ("lower", "upper", "velocity"):
            if mj[jn]["kind"] == "continuous" and key != "velocity":
                continue
            if abs(float(ml.get(key, "nan")) - float(ol.get(key, "nan"))) > 1e-12:
                problems.append(f"{jn}: {key} {ol.get(key)} != maker's {ml.get(key)}")
    dp = dr = 0.0
    for _ in range(SAMPLES):
        q = dict((jn, rng.uniform(j["q_min"], j["q_max"])) for jn, j in zip(names, desc["joint"]))
        a, b = ours.flange(base, flange, q), maker.flange(base, flange, q)
        dp = max(dp, float(np.abs(a[:3, 3] - b[:3, 3]).max()))
        m = a[:3, :3].T @ b[:3, :3]
        w = [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]
        dr = max(dr, math.atan2(np.linalg.norm(w), np.trace(m) - 1))
    ok = dp <= TOL and dr <= TOL and not problems
    print(f"{name:8} {written} {base}->{flange}: {SAMPLES} configurations, worst |Δp| {dp:.2e} m, "
          f"|Δθ| {dr:.2e} rad vs {fixture.relative_to(root)} {'ok' if ok else 'FAIL'}")
    for p in problems:
        print(f"  {p}")
    return ok


def check_poses(urdf, base, flange, poses, tol):
    """The pose of `flange` in `base` of the URDF file `urdf` (its revolute
    joints in chain order) against the rows of `poses`: q of each joint,
    then the position (3) and the rotation matrix row by row (9)."""
    u = Urdf(urdf)
    names = [j["name"] for j in u.path(flange) if j["kind"] in ("revolute", "continuous")]
    dp = dr = 0.0
    rows = 0
    for line in Path(poses).read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        v = [float(x) for x in line.split(",")]
        n = len(names)
        q, p, r = v[:n], np.array(v[n:n + 3]), np.array(v[n + 3:n + 12]).reshape(3, 3)
        a = u.flange(base, flange, dict(zip(names, q)))
        dp = max(dp, float(np.abs(a[:3, 3] - p).max()))
        m = a[:3, :3].T @ r
        w = [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]
        dr = max(dr, math.atan2(np.linalg.norm(w), np.trace(m) - 1))
        rows += 1
    ok = rows > 0 and dp <= tol and dr <= tol
    print(f"{urdf} {base}->{flange} ({len(names)} joints): {rows} configurations, "
          f"worst |Δp| {dp:.2e} m, |Δθ| {dr:.2e} rad {'ok' if ok else 'FAIL'}")
    return ok


def main():
    rng = np.random.default_rng(38)
    if len(sys.argv) > 1 and sys.argv[1] == "--poses":
        urdf, base, flange, poses = sys.argv[2:6]
        tol = float(sys.argv[6]) if len(sys.argv) > 6 else TOL
        sys.exit(0 if check_poses(urdf, base, flange, poses, tol) else 1)
    rng_u = type("R", (), {"uniform": lambda self, a, b: float(rng.uniform(a, b))})()
    if len(sys.argv) > 1 and sys.argv[1] == "--written":
        name, written = sys.argv[2], Path(sys.argv[3])
        root = Path(sys.argv[4]) if len(sys.argv) > 4 else Path(__file__).resolve().parent.parent
        sys.exit(0 if check_written(root, name, written, rng_u) else 1)
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    names = sys.argv[2:] or sorted(p.stem for p in (root / "tests/fixtures/makers").glob("*.urdf"))
    ok = all([check(root, n, rng_u) for n in names])
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
