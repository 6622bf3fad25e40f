#!/usr/bin/env python3
"""Reads joint positions from a UR controller with ur_rtde's
RTDEReceiveInterface (SDU Robotics' `ur-rtde` from PyPI), as UR users
record them, for issue 38's check against robimu's simulated controller.

usage: ur_rtde_receive.py HOST SECONDS

Prints one JSON object: the number of readings, the controller timestamps'
first and last value, the mean of each joint's actual_q, and the largest
gap between consecutive controller timestamps. Exits 3 when ur_rtde is not
installed (the caller skips), 1 on any error from ur_rtde.
"""

import json
import sys
import time

try:
    import rtde_receive
except ImportError as e:  # the caller decides whether this is a skip
    print(f"ur_rtde is not installed: {e}", file=sys.stderr)
    sys.exit(3)


def main() -> int:
    host, seconds = sys.argv[1], float(sys.argv[2])
    # timestamp and actual_q only: the recipe robimu records with
    rtde = rtde_receive.RTDEReceiveInterface(host, 500.0, ["timestamp", "actual_q"])
    stamps, qs = [], []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not rtde.isConnected():
            print("ur_rtde lost the connection", file=sys.stderr)
            return 1
        stamps.append(rtde.getTimestamp())
        qs.append(rtde.getActualQ())
        time.sleep(0.01)
    rtde.disconnect()
    mean = [sum(q[j] for q in qs) / len(qs) for j in range(6)]
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    print(
        json.dumps(
            {
                "readings": len(qs),
                "first_timestamp": stamps[0],
                "last_timestamp": stamps[-1],
                "mean_q": mean,
                "largest_gap_s": max(gaps) if gaps else None,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
