#!/bin/sh
# Regenerates the equal-time studies of docs/benchmarks.md: every listed integrator on four shipped
# scenes, against the references in references/ (scripts/make-references.sh), at the references'
# resolution (128×128; veach-ajar 160×90), every integrator with max_depth = 8 as the references.
#
# Usage: scripts/benchmarks.sh [INTEGRATORS] [TIMES] [SEEDS]
#   defaults: all integrators this binary knows, budgets 1,2,4 s, 2 seeds; 2 threads.
#   docs/benchmarks.md was made with: scripts/benchmarks.sh all 3,6,12 3   (~25 min on 2 cores)
# Writes docs/bench/<scene>-converge.{csv,md}, docs/img/<scene>-converge.png, docs/bench/machine.txt,
# and docs/benchmarks.md (scripts/benchmarks_page.py).
# The binary is $PLEXUS if set, else the release build (built here if missing).
set -eu
cd "$(dirname "$0")/.."
if [ -z "${PLEXUS:-}" ]; then
    cargo build --release --quiet
    PLEXUS="${CARGO_TARGET_DIR:-target}/release/plexus"
fi
INTEGRATORS="${1:-all}"
TIMES="${2:-1,2,4}"
SEEDS="${3:-2}"
mkdir -p docs/bench docs/img
# What the page must say about where the numbers came from (scripts/benchmarks_page.py reads it).
{
    printf '%s, %s cores, %s GiB; plexus at commit %s; run %s, load average %s when it started\n' \
        "$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)" "$(nproc)" \
        "$(awk '/MemTotal/ {printf "%.0f", $2 / 1048576}' /proc/meminfo)" \
        "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" "$(date -u +%Y-%m-%d)" \
        "$(cut -d' ' -f1 /proc/loadavg)"
} > docs/bench/machine.txt
for scene in cornell-box cornell-glossy cornell-glass veach-ajar; do
    "$PLEXUS" converge "scenes/$scene.toml" --reference "references/$scene.exr" \
        --integrators "$INTEGRATORS" --times "$TIMES" --seeds "$SEEDS" --threads 2 --set max_depth=8 \
        --out-dir docs/bench
    mv "docs/bench/$scene-converge.png" "docs/img/$scene-converge.png"
done
# The page: tables, plots and the summary regenerate; docs/bench/reading.md (the interpretation) is
# written by hand and must be revisited when the numbers change.
if command -v python3 >/dev/null 2>&1; then
    python3 scripts/benchmarks_page.py
    echo "docs/benchmarks.md rewritten; revisit docs/bench/reading.md against the new numbers" >&2
else
    echo "python3 not found: run scripts/benchmarks_page.py to rewrite docs/benchmarks.md" >&2
fi
