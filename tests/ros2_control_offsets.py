#!/usr/bin/env python3
"""Check a `robimu export --format ros2-control` file, independently.

Reads the offsets with ElementTree as ros2_control's SimpleTransmission uses
them (joint position = actuator position / mechanical_reduction + offset),
and the robot's nominal and calibrated URDFs with the numpy reader of
tests/makers_fk.py. At 200 random configurations within the nominal URDF's
limits it prints the mean flange error (mm) against the calibrated model of
the nominal model read at q (no offsets), at q + offset (as ros2_control
reports the joints) and at q - offset (the opposite sign):

    python3 tests/ros2_control_offsets.py NOMINAL.urdf CALIBRATED.urdf OFFSETS.xml BASE FLANGE
"""

import sys
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from makers_fk import Urdf  # noqa: E402


def offsets(path):
    out = {}
    for t in ET.parse(path).getroot().iter("transmission"):
        assert t.findtext("plugin") == "transmission_interface/SimpleTransmission"
        j = t.find("joint")
        n = float(j.findtext("mechanical_reduction"))
        out[j.get("name")] = (n, float(j.findtext("offset")))
    return out


def main():
    nominal, calibrated = Urdf(sys.argv[1]), Urdf(sys.argv[2])
    off = offsets(sys.argv[3])
    base, flange = sys.argv[4], sys.argv[5]
    chain = [j for j in nominal.path(flange) if j["kind"] in ("revolute", "continuous")]
    names = [j["name"] for j in chain]
    assert sorted(names) == sorted(off), (names, sorted(off))
    rng = np.random.default_rng(40)
    err = {"nominal": [], "plus": [], "minus": []}
    for _ in range(200):
        q = {j["name"]: rng.uniform(float(j["limit"]["lower"]), float(j["limit"]["upper"])) for j in chain}
        want = calibrated.flange(base, flange, q)
        for key, sign in (("nominal", 0), ("plus", 1), ("minus", -1)):
            # the actuator reads q; the joint position the description sees
            qj = {k: v / off[k][0] + sign * off[k][1] for k, v in q.items()}
            got = nominal.flange(base, flange, qj)
            err[key].append(1e3 * np.linalg.norm(got[:3, 3] - want[:3, 3]))
    print(" ".join(f"{k}={np.mean(v):.6f}" for k, v in err.items()), "mm mean over 200 configurations")


if __name__ == "__main__":
    main()
