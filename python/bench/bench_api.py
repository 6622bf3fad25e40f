"""Benchmarks of the Python API (issue 40): what the Python layer costs.

1. ``robimu.calibrate(session)`` against the in-memory Rust call it wraps
   (``Prepared::new`` + ``fit`` with the default settings, timed inside the
   same extension: ``robimu._native.bench_rust_calibrate``) on a simulated
   300 s AUBO i5 session; the runs alternate, the figure is the ratio of
   the medians (target ≤ 1.1).
2. Converting a 1 kHz × 300 s session to NumPy arrays: the first access
   to ``Session.joint_t``, ``Session.joints`` and ``Session.imu(0)`` on a
   freshly loaded session (the file reading is not counted; target ≤ 50 ms).

Run it with a wheel built in release (``maturin build --release -m
python/Cargo.toml``) installed:

    python python/bench/bench_api.py [--runs 5]
"""

import argparse
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import robimu
from robimu import _native


def calibrate_ratio(runs: int, tmp: Path) -> None:
    s = robimu.simulate("aubo_i5", duration=300, seed=1, out=tmp / "s300")
    robimu.calibrate(s)  # warm: page faults, the allocator's pools
    py, rust = [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        robimu.calibrate(s)
        py.append(time.perf_counter() - t0)
        rust.append(_native.bench_rust_calibrate(s._native))
    mp, mr = statistics.median(py), statistics.median(rust)
    print(f"calibrate, 300 s session ({runs} runs each, alternating):")
    print(f"  robimu.calibrate        median {mp:.3f} s  (runs {', '.join(f'{x:.3f}' for x in py)})")
    print(f"  in-memory Rust call     median {mr:.3f} s  (runs {', '.join(f'{x:.3f}' for x in rust)})")
    print(f"  ratio {mp / mr:.3f} (target <= 1.1)")


def numpy_conversion(runs: int, tmp: Path) -> None:
    d = tmp / "s1k"
    robimu.simulate("aubo_i5", duration=300, seed=1, rate=1000, out=d)
    times = []
    for _ in range(runs):
        s = robimu.Session.load(d)
        t0 = time.perf_counter()
        t, q, imu = s.joint_t, s.joints, s.imu(0)
        times.append(time.perf_counter() - t0)
    n = len(t) + len(imu.t)
    print(f"NumPy conversion, 1 kHz x 300 s ({len(t)} joint rows x {q.shape[1]}, {len(imu.t)} IMU rows; {n} rows):")
    print(f"  median {1e3 * statistics.median(times):.1f} ms  (runs {', '.join(f'{1e3 * x:.1f}' for x in times)}; target <= 50 ms)")


def main() -> None:
    warnings.simplefilter("ignore", robimu.RobimuWarning)  # the weak-directions note, each run
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        numpy_conversion(a.runs, Path(tmp))
        calibrate_ratio(a.runs, Path(tmp))


if __name__ == "__main__":
    main()
