#!/bin/sh
# The RJMLT benchmark (issue 6): MMLT against RJMLT at equal time on three shipped scenes, 10 seeds
# each, MSE against the path-traced references in references/ (scripts/make-references.sh), and
# the acceptance table of the RJMLT paper's Fig. 4 on each scene.
#
# Usage: docs/lab/scripts/bench-rjmlt.sh [TIME] [SEEDS] [HARD_TIME] [SCENES]
#   defaults: 8 s per render on the Cornell scenes and HARD_TIME = 30 s on veach-ajar (at 8 s its
#   MLT images are still dominated by start-up blotches), 10 seeds, 2 threads,
#   SCENES = "cornell-glossy cornell-glass veach-ajar".
# Writes docs/lab/data/rjmlt/<scene>-converge.{csv,md,png} and docs/lab/data/rjmlt/<scene>-fig4.md.
# Every integrator runs with max_depth = 8 (the references' depth and the MLT default).
# The binary is $PLEXUS if set, else the release build (built here if missing).
set -eu
cd "$(dirname "$0")/../../.."
TIME="${1:-8}"
SEEDS="${2:-10}"
HARD_TIME="${3:-30}"
SCENES="${4:-cornell-glossy cornell-glass veach-ajar}"
if [ -z "${PLEXUS:-}" ]; then
    cargo build --release --quiet
    PLEXUS="${CARGO_TARGET_DIR:-target}/release/plexus"
fi
export PLEXUS
out=docs/lab/data/rjmlt
mkdir -p "$out"
for scene in $SCENES; do
    budget=$TIME
    if [ "$scene" = veach-ajar ]; then
        budget=$HARD_TIME
    fi
    "$PLEXUS" converge "scenes/$scene.toml" --reference "references/$scene.exr" \
        --integrators mmlt,rjmlt --times "$budget" --seeds "$SEEDS" --threads 2 --set max_depth=8 --out-dir "$out"
    # The acceptance table: one render per method at the reference's resolution and the same budget.
    res=$(python3 -c "import json; r = json.load(open('references/$scene.json'))['resolution']; print('%dx%d' % tuple(r))")
    tmp=$(mktemp -d)
    for method in mmlt rjmlt; do
        "$PLEXUS" reference "scenes/$scene.toml" --integrator "$method" --time "$budget" --seed 1 --threads 2 \
            --resolution "$res" --set max_depth=8 --out "$tmp/$method.exr" >&2
    done
    python3 scripts/fig4_table.py "$tmp/mmlt.json" "$tmp/rjmlt.json" > "$out/$scene-fig4.md"
    rm -rf "$tmp"
done
