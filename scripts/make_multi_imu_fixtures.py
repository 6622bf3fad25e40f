#!/usr/bin/env python3
"""Writes the result fixtures of host/cli/tests/fixtures/multi_imu/: an AUBO i5
calibration result (docs/model.md §8) for K = 1, 2 and 3 IMUs (§9 names), and
truth.toml files to compare them with. Deterministic; run from the repository
root. The values are made up (prior mean + a fraction of the prior σ); the
covariance is D·C·D with C tridiagonal (ρ = 0.3, positive definite), D the σ.
"""
import json
import math
from pathlib import Path

DEG = math.pi / 180
OUT = Path("host/cli/tests/fixtures/multi_imu")


def shared_names():
    """The 18 shared robot errors of the AUBO i5 and g (docs/model.md §6.3)."""
    eps = [("eps_1_1", "m", 0.0, 0.001), ("eps_1_6", "rad", 0.0, DEG)]
    for i in range(2, 6):
        eps += [(f"eps_{i}_1", "m", 0.0, 0.001), (f"eps_{i}_2", "m", 0.0, 0.001),
                (f"eps_{i}_4", "rad", 0.0, DEG), (f"eps_{i}_6", "rad", 0.0, DEG)]
    g = [("g_x", "m/s^2", 0.0, 0.5), ("g_y", "m/s^2", 0.0, 0.5)]
    return eps, g


def imu_names():
    """The 28 parameters of one IMU in x order: position, τ, 24 intrinsics."""
    pos = [("eps_6_1", "m", 0.0252, 0.01), ("eps_6_2", "m", 0.0783, 0.01),
           ("eps_6_3", "m", 0.0182, 0.01)]
    tau = [("tau", "s", 0.0, 1.0)]
    sensor = []
    for s, unit_b, g_sigma, b_sigma in [("a", "m/s^2", 1.5 * DEG, 2.0),
                                          ("w", "rad/s", 2.0 * DEG, 5.0 * DEG)]:
        sensor += [(f"gamma_{s}_{ax}", "rad", 0.0, g_sigma) for ax in ("yz", "zy", "zx")]
        sensor += [(f"r_{s}_z", "rad", math.pi, 5 * DEG), (f"r_{s}_y", "rad", 0.0, 5 * DEG),
                   (f"r_{s}_x", "rad", 0.0, 5 * DEG)]
        sensor += [(f"k_{s}_{ax}", "1", 1.0, 0.1) for ax in "xyz"]
        sensor += [(f"b_{s}_{ax}", unit_b, 0.0, b_sigma) for ax in "xyz"]
    return pos, tau, sensor


FROZEN = {"eps_1_1"} | {f"eps_{i}_{k}" for i in range(2, 6) for k in (1, 2)}


def layout(k, order):
    """(name, unit, prior, prior σ) in x order for k IMUs."""
    eps, g = shared_names()
    pos, tau, sensor = imu_names()
    per = lambda j: [((n if j == 0 else f"imu{j}/{n}"), u, p, s) for n, u, p, s in pos + tau + sensor]
    if order == "k1":  # the one-IMU layout (§5), further IMUs appended
        first = eps + pos + g + tau + sensor
    else:  # §9: shared robot errors and g, then 28 per IMU
        first = eps + g + per(0)
    return first + [p for j in range(1, k) for p in per(j)]


def result(k, order):
    specs = layout(k, order)
    params, est = [], []
    truth = {}
    for idx, (name, unit, prior, ps) in enumerate(specs):
        frozen = name in FROZEN
        value = prior if frozen else prior + 0.4 * math.sin(1.7 * idx + 0.3) * ps
        sigma = 0.0 if frozen else ps * 10 ** (-((idx * 5) % 11) / 5)
        params.append({"name": name, "unit": unit, "value": value, "prior": prior,
                       "prior_sigma": ps, "sigma": sigma, "frozen": frozen})
        if not frozen:
            est.append((name, sigma))
        truth[name] = value - (0.0 if frozen else 1.1 * math.cos(2.3 * idx) * sigma)
    n = len(est)
    matrix = [[0.0] * n for _ in range(n)]
    for i in range(n):
        matrix[i][i] = est[i][1] ** 2
        if i + 1 < n:
            c = 0.3 * est[i][1] * est[i + 1][1]
            matrix[i][i + 1] = matrix[i + 1][i] = c
    r = {
        "format": "robimu-result/1",
        "parameters": params,
        "covariance": {"names": [e[0] for e in est], "matrix": matrix},
        "robot": "aubo_i5",
        "priors_used": True,
        "tau_initial": -0.0123,
        "knot_spacing": 0.5,
        "iterations": 9,
        "initial_cost": 123456.75,
        "final_cost": 43210.5,
        "termination": "converged (relative cost change below 1e-10)",
        "residual_rms": [1.01, 0.99, 1.02, 0.98, 1.0, 1.03],
        "imu_samples_used": 36000 * k,
        "noise_model": {"kind": "white"},
        "verdict": {"trust": "good", "reasons": [], "checks": [
            {"topic": "converged", "ok": True, "text": "converged in 9 iterations"},
            {"topic": "residuals", "ok": True, "text": "white: Ljung-Box p > 0.0017 on every channel"},
        ]},
        "weak_directions": [{"relative_information": 0.002, "parameters": [
            {"name": "eps_2_4", "share": 0.6}, {"name": "eps_3_4", "share": 0.35}]}],
    }
    return r, truth


def write_truth(path, truth):
    lines = ["# made-up truth of the fixture result (scripts/make_multi_imu_fixtures.py)"]
    for name, v in truth.items():
        key = name if "/" not in name else f'"{name}"'
        lines.append(f"{key} = {v!r}")
    path.write_text("\n".join(lines) + "\n")


OUT.mkdir(parents=True, exist_ok=True)
for k, order in [(1, "k1"), (2, "s9"), (3, "k1")]:
    r, truth = result(k, order)
    (OUT / f"result{k}.json").write_text(json.dumps(r, indent=2) + "\n")
    write_truth(OUT / f"truth{k}.toml", truth)
