#!/bin/sh
# Regenerates the equal-time studies of docs/benchmarks.md: every listed integrator on four shipped
# scenes, against the references in references/ (scripts/make-references.sh), at the references'
# resolution (128×128; veach-ajar 160×90), every integrator with max_depth = 8 as the references.
#
# Usage: scripts/benchmarks.sh [INTEGRATORS] [TIMES] [SEEDS]
#   defaults: all integrators this binary knows, budgets 1,2,4 s, 2 seeds; 2 threads.
# Writes docs/bench/<scene>-converge.{csv,md} and docs/img/<scene>-converge.png.
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
for scene in cornell-box cornell-glossy cornell-glass veach-ajar; do
    "$PLEXUS" converge "scenes/$scene.toml" --reference "references/$scene.exr" \
        --integrators "$INTEGRATORS" --times "$TIMES" --seeds "$SEEDS" --threads 2 --set max_depth=8 \
        --out-dir docs/bench
    mv "docs/bench/$scene-converge.png" "docs/img/$scene-converge.png"
done
