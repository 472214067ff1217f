#!/bin/sh
# Regenerates the reference images in references/ that docs/benchmarks.md and `plexus converge`
# use: long path-traced renders at a reduced resolution (same aspect ratio as each scene), with a
# fixed seed that convergence studies do not use (they use seeds 0, 1, 2, ...), and the path depth
# the benchmarks give every integrator (max_depth = 8, the MLT papers' L), so that an image's error
# is its noise and not a difference in which paths it counts.
#
# Usage: scripts/make-references.sh [SPP]      (default 4096 samples per pixel; veach-ajar gets 2×,
#                                                its light reaches the room only through the door gap)
# The binary is $PLEXUS if set, else the release build (built here if missing).
# Each reference is written with a JSON file beside it recording how it was made.
set -eu
cd "$(dirname "$0")/.."
SPP="${1:-4096}"
SEED=1000003
if [ -z "${PLEXUS:-}" ]; then
    cargo build --release --quiet
    PLEXUS="${CARGO_TARGET_DIR:-target}/release/plexus"
fi
mkdir -p references
# scene            resolution  spp multiplier
for entry in "cornell-box 128x128 1" "cornell-glossy 128x128 1" "cornell-glass 128x128 1" "veach-ajar 160x90 2"; do
    set -- $entry
    "$PLEXUS" reference "scenes/$1.toml" --integrator pt --spp $((SPP * $3)) --seed "$SEED" \
        --resolution "$2" --set max_depth=8 --out "references/$1.exr"
done
# environment (issue 17): the objects under the procedural sky, at 4:3 like the scene (the emlt
# share tests render it at 16×12). pt with next-event estimation of the environment.
"$PLEXUS" reference scenes/environment.toml --integrator pt --spp "$SPP" --seed "$SEED" \
    --resolution 128x96 --set max_depth=8 --out references/environment.exr
# portal-planes (issue 15): light reaches the reflector only through a small hole, which BDPT's
# light subpaths find far more often than pt's paths; 2× the samples at its 32×32 test resolution.
"$PLEXUS" reference scenes/portal-planes.toml --integrator bdpt --spp $((SPP * 2)) --seed "$SEED" \
    --resolution 32x32 --set max_depth=8 --out references/portal-planes.exr
# breakfast-window (issue 15): the breakfast room lit by the procedural sky (scenes/environment/
# sky.exr, its sun shining in) through its one window, at its 32×32 test resolution. pt with
# next-event estimation of the environment finds the sun through the window directly; light
# subpaths from the environment would mostly miss the window. 8× the samples: the share test's
# reference noise must stay well below the chains'.
"$PLEXUS" reference scenes/breakfast-window.toml --integrator pt --spp $((SPP * 8)) --seed "$SEED" \
    --resolution 32x32 --set max_depth=8 --out references/breakfast-window.exr
# breakfast-window's share test (tests/chains/portal.rs) needs the reference's noise, which one image
# cannot give honestly (estimated from its pixels at 32×32, the room's edges count as noise): 16
# independent pt renders of 2048 spp (seeds SEED + k), whose spread measures the reference side's
# variance the same way the 16 pmlt renders measure theirs. Together 32,768 spp, as the image above.
mkdir -p references/breakfast-window-parts
for k in $(seq 1 16); do
    "$PLEXUS" reference scenes/breakfast-window.toml --integrator pt --spp $((SPP / 2)) --seed $((SEED + k)) \
        --resolution 32x32 --set max_depth=8 --out "references/breakfast-window-parts/$(printf %02d "$k").exr"
done
# The refraction scenes: a lamp sealed in a flat glass slab (smooth and rough) and a glass prism
# under a lamp, whose light-direction refractions do not cancel (the measure factor of
# src/integrator/path_space/density.rs): the path-space and primary-sample-space MLT agreement
# tests (tests/chains/refraction.rs) compare their region shares with these, at 32×32.
for s in glass-lamp glass-lamp-rough glass-prism; do
    "$PLEXUS" reference "scenes/$s.toml" --integrator pt --spp "$SPP" --seed "$SEED" \
        --resolution 128x128 --set max_depth=8 --out "references/$s.exr"
done
# staircase (issue 17's emlt benchmark): the imported staircase (scenes/imported/staircase.toml,
# 720×1280) at 72×128 and 1024 spp (about 60 CPU s): its pt noise is measured against a second,
# independent 256-spp render in docs/lab/benchmarks-history.md's issue 17 section.
"$PLEXUS" reference scenes/imported/staircase.toml --integrator pt --spp $((SPP / 4)) --seed "$SEED" \
    --resolution 72x128 --set max_depth=8 --out references/staircase.exr
