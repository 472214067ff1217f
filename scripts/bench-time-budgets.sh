#!/usr/bin/env bash
# How well every integrator keeps a `--time` budget: one render each of the Cornell box at 64×64
# (a pass is one sample per pixel, or about one mutation per pixel for MLT: a few tens of ms),
# printing the budget, the wall time measured around the process, the time the render reports
# (setup, MLT's bootstrap included) and the overrun. The driver starts a pass only if it is
# predicted to end before the deadline, so on an unloaded machine the render should end within one
# pass of the budget; the test suite used to assert <= 1.1 * budget + 0.25 s here, which a loaded
# machine fails without a bug, so the logic is tested on a fake clock (integrator::driver) and
# the wall-clock figure lives here. State the machine and its load with the numbers.
#
# Usage: scripts/bench-time-budgets.sh
# Environment (defaults in brackets):
#   PLEXUS    binary           [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   TIME      budget, seconds  [1.5]
#   THREADS   render threads   [2]
#   OUTDIR    where images and JSON go [/tmp/bench-time-budgets]
set -euo pipefail

budget=${TIME:-1.5}
threads=${THREADS:-2}
outdir=${OUTDIR:-/tmp/bench-time-budgets}
source "$(dirname "$0")/plexus-binary.sh"
plexus_binary bench-time-budgets
root=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$outdir"
# The Cornell box at 64×64 (the scene refers to no other file, so a copy anywhere renders).
sed 's/^resolution = .*/resolution = [64, 64]/' "$root/scenes/cornell-box.toml" > "$outdir/cornell-64.toml"

echo "| integrator | budget s | measured s | reported s | overrun |"
echo "|---|---:|---:|---:|---:|"
for name in pt bdpt light pssmlt mmlt rjmlt; do
    start=$(date +%s.%N)
    CI=true "$plexus" render "$outdir/cornell-64.toml" --integrator "$name" --time "$budget" --threads "$threads" \
        --seed 1 --out "$outdir/$name.exr" >"$outdir/$name.log" 2>&1 || { cat "$outdir/$name.log" >&2; exit 1; }
    end=$(date +%s.%N)
    python3 - "$outdir/$name.json" "$name" "$budget" "$start" "$end" <<'PY'
import json, sys
path, name, budget, start, end = sys.argv[1:]
s = json.load(open(path))
budget, measured = float(budget), float(end) - float(start)
print(f"| {name} | {budget:g} | {measured:.3f} | {s['wall_time_s']:.3f} | {100 * (s['wall_time_s'] / budget - 1):+.1f}% |")
PY
done
