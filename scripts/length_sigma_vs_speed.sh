#!/usr/bin/env bash
# Posterior σ of a robot's link lengths against the speed and acceleration
# of a planned motion (issue 38; docs/guide/robots.md, "Link lengths at a
# robot's limits"). For each factor, the built-in robot's joint speed and/or
# acceleration limits are scaled, a motion of DURATION s is planned at those
# limits (`robimu plan`) and its σ computed (`robimu identifiability`);
# prints the largest and smallest σ of the lengths (ε_i1, ε_i2, i < 6), mm.
#
# usage: scripts/length_sigma_vs_speed.sh [ROBOT] [DURATION] [OUT_DIR]
#   e.g. scripts/length_sigma_vs_speed.sh ur5e 300 /tmp/lengths
# Uses `robimu` from PATH, else target/release/robimu (cargo build --release).
set -euo pipefail
robot=${1:-ur5e}
duration=${2:-300}
out=${3:-$(mktemp -d)}
bin=$(command -v robimu || echo "$(dirname "$0")/../target/release/robimu")
mkdir -p "$out"
"$bin" robots show "$robot" > "$out/$robot.toml"
printf '%-28s %10s %10s  %s\n' "limits" "worst mm" "best mm" "worst length"
# (speed factor, acceleration factor)
for pair in "0.25 0.25" "0.5 0.5" "1 1" "1 2" "1 4" "1 8"; do
    set -- $pair
    tag="v$1-a$2"
    python3 - "$out/$robot.toml" "$out/$tag.toml" "$1" "$2" <<'PY'
import re, sys
src, dst, fv, fa = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
text = open(src).read()
scale = {"qd_max": fv, "qdd_max": fa}
text = re.sub(r"^(qd_max|qdd_max) = (\S+)",
              lambda m: f"{m.group(1)} = {float(m.group(2)) * scale[m.group(1)]!r}", text, flags=re.M)
open(dst, "w").write(text)
PY
    "$bin" plan --robot "$out/$tag.toml" --duration "$duration" --out "$out/plan-$tag" > "$out/plan-$tag.log" 2>&1
    mkdir -p "$out/id-$tag"
    "$bin" identifiability --plan "$out/plan-$tag" --robot "$out/$tag.toml" --speeds 1 --random 1 \
        --no-check --out "$out/id-$tag" > "$out/id-$tag.log" 2>&1
    python3 - "$out/id-$tag/sigma_vs_time.csv" "$1" "$2" <<'PY'
import csv, sys
last = list(csv.DictReader(open(sys.argv[1])))[-1]
lengths = {k: float(v) * 1e3 for k, v in last.items()
           if k.startswith("eps_") and k[-1] in "12" and not k.startswith("eps_6")}
worst = max(lengths, key=lengths.get)
label = f"speed x{sys.argv[2]}, acceleration x{sys.argv[3]}"
print(f"{label:28} {lengths[worst]:10.3f} {min(lengths.values()):10.3f}  {worst}")
PY
done
echo "plans and tables in $out"
