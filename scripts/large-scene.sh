#!/usr/bin/env bash
# Issue 20's large-scene measurement (docs/lab/benchmarks-history.md, "Large scenes"): loads the 10,008,338-
# triangle displaced grid with each accelerator through `plexus info` (read the PLY, build the
# scene and the accelerator, print the memory estimate) under /usr/bin/time -v, one run at a time,
# and prints a Markdown table of wall time, CPU time, peak resident memory and `info`'s estimate.
#
#   scripts/large-scene.sh [DIR]        (default DIR: target/large-scene; PLEXUS=path overrides
#                                        the binary, default target/release/plexus; REPS=n runs
#                                        each accelerator n times)
#
# IDLE=1 runs each load under SCHED_FIFO (`chrt -f 10`, needs root), which on a machine busy with
# other work gives the load both cores as an idle machine would (the kernel still keeps 5% of each
# second for everything else): the wall time is then close to an idle machine's. Without it the
# wall time on a loaded machine is mostly waiting for a core; the CPU time is comparable either way.
#
# Generates DIR/large-grid.ply (190 MB) and DIR/large-scene.toml with scripts/large-scene.py if
# they are missing. Needs about 8 GB of free memory for the old reader, under 1.5 GB for the new.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DIR="${1:-$ROOT/target/large-scene}"
PLEXUS="${PLEXUS:-$ROOT/target/release/plexus}"
REPS="${REPS:-1}"
RUN=()
[ "${IDLE:-0}" = 1 ] && RUN=(chrt -f 10)
[ -f "$DIR/large-grid.ply" ] || python3 "$ROOT/scripts/large-scene.py" "$DIR"

echo "load average: $(cut -d' ' -f1-3 /proc/loadavg); binary: $PLEXUS; ${RUN[*]:-normal scheduling}"
echo
echo "| accelerator | run | wall s | CPU s (user + sys) | peak RSS MiB | info estimate MiB | estimate / peak |"
echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"
for accel in embree bvh; do
    for rep in $(seq 1 "$REPS"); do
        "${RUN[@]}" /usr/bin/time -v -o "$DIR/time-$accel.txt" \
            "$PLEXUS" info "$DIR/large-scene.toml" --accel "$accel" --json >"$DIR/info-$accel.json"
        python3 - "$DIR/time-$accel.txt" "$DIR/info-$accel.json" "$accel" "$rep" <<'PY'
import json, sys
t = {}
for line in open(sys.argv[1]):
    k, _, v = line.strip().rpartition(": ")
    t[k] = v
h, m, s = (["0"] + t["Elapsed (wall clock) time (h:mm:ss or m:ss)"].split(":"))[-3:]
wall = 3600 * float(h) + 60 * float(m) + float(s)
cpu = float(t["User time (seconds)"]) + float(t["System time (seconds)"])
peak = int(t["Maximum resident set size (kbytes)"]) / 1024
# The scene's part of the estimate (SceneMemory::total: the corner copies and the accelerator's
# build temporaries are never held at once, so the larger of the two counts).
total = json.load(open(sys.argv[2]))["memory"]["total"] / 2**20
print(f"| {sys.argv[3]} | {sys.argv[4]} | {wall:.1f} | {cpu:.1f} | {peak:.0f} | {total:.0f} | {total / peak:.2f} |")
PY
    done
done
