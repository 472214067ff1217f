#!/bin/sh
# Regenerates the reference images in references/ that docs/benchmarks.md and `plexus converge`
# use: long path-traced renders at a reduced resolution (same aspect ratio as each scene), with a
# fixed seed that convergence studies do not use (they use seeds 0, 1, 2, ...).
#
# Usage: scripts/make-references.sh [SPP]      (default 512 samples per pixel)
# The binary is $PLEXUS if set, else the release build (built here if missing).
# Each reference is written with a JSON file beside it recording how it was made.
set -eu
cd "$(dirname "$0")/.."
SPP="${1:-512}"
SEED=1000003
if [ -z "${PLEXUS:-}" ]; then
    cargo build --release --quiet
    PLEXUS="${CARGO_TARGET_DIR:-target}/release/plexus"
fi
mkdir -p references
# scene            resolution
for entry in "cornell-box 128x128" "cornell-glossy 128x128" "cornell-glass 128x128"; do
    set -- $entry
    "$PLEXUS" reference "scenes/$1.toml" --integrator pt --spp "$SPP" --seed "$SEED" \
        --resolution "$2" --out "references/$1.exr"
done
