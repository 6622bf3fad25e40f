#!/usr/bin/env python3
"""Compare two robimu result files: the largest |Δvalue|/σ and |Δσ|/σ over
the estimated parameters (the check that a speed change kept the estimate).

    python3 scripts/compare_results.py A.json B.json [--tol 1e-6]
"""
import json
import sys


def params(path):
    with open(path) as f:
        return {p["name"]: p for p in json.load(f)["parameters"]}


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    tol = float(sys.argv[sys.argv.index("--tol") + 1]) if "--tol" in sys.argv else 1e-6
    if len(args) < 2:
        sys.exit(__doc__)
    a, b = params(args[0]), params(args[1])
    if a.keys() != b.keys():
        sys.exit("the files estimate different parameters")
    worst_v, worst_s = (0.0, ""), (0.0, "")
    for name, p in a.items():
        if p["frozen"] or p["sigma"] <= 0:
            continue
        dv = abs(p["value"] - b[name]["value"]) / p["sigma"]
        ds = abs(p["sigma"] - b[name]["sigma"]) / p["sigma"]
        worst_v = max(worst_v, (dv, name))
        worst_s = max(worst_s, (ds, name))
    print(f"max |dvalue|/sigma = {worst_v[0]:.3e} ({worst_v[1]}), "
          f"max |dsigma|/sigma = {worst_s[0]:.3e} ({worst_s[1]})")
    sys.exit(0 if max(worst_v[0], worst_s[0]) <= tol else 1)


if __name__ == "__main__":
    main()
