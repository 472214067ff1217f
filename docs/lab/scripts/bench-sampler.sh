#!/bin/sh
# MSE at equal samples, independent against Owen-scrambled Sobol sampling (issue 20), on the four
# benchmark scenes against their references (references/, 4096 spp pt at max_depth 8): pt, BDPT and
# the light tracer at the references' resolution and depth, SEEDS seeds each.
#
# Usage: docs/lab/scripts/bench-sampler.sh [SEEDS] [PT_SPP] [BDPT_SPP]    (defaults 3, "16 64", 16)
# Prints a Markdown table (mean MSE over the seeds per row, and the ratio Sobol / independent);
# the table in docs/lab/benchmarks-history.md ("Sobol sampling") was made with the defaults.
# The binary is $PLEXUS if set, else the release build (built here if missing).
set -eu
cd "$(dirname "$0")/../../.."
if [ -z "${PLEXUS:-}" ]; then
    cargo build --release --quiet
    PLEXUS="${CARGO_TARGET_DIR:-target}/release/plexus"
fi
SEEDS="${1:-3}"
PT_SPP="${2:-16 64}"
BDPT_SPP="${3:-16}"
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT

# mean MSE over the seeds of INTEGRATOR at SPP with SAMPLER on SCENE (resolution RES)
mse() {
    scene=$1 res=$2 integrator=$3 spp=$4 sampler=$5
    total=0
    s=1
    while [ "$s" -le "$SEEDS" ]; do
        "$PLEXUS" reference "scenes/$scene.toml" --integrator "$integrator" --spp "$spp" --seed "$s" \
            --resolution "$res" --threads 2 --set max_depth=8 --set "sampler=\"$sampler\"" \
            --out "$TMP/img.exr" >/dev/null 2>&1
        m=$("$PLEXUS" compare "$TMP/img.exr" "references/$scene.exr" --json |
            python3 -c 'import json,sys; print(json.load(sys.stdin)["mse"])')
        total=$(python3 -c "print($total + $m)")
        s=$((s + 1))
    done
    python3 -c "print($total / $SEEDS)"
}

echo "| scene | integrator | spp | MSE independent | MSE Sobol | Sobol / independent |"
echo "| --- | --- | --- | --- | --- | --- |"
for entry in "cornell-box 128x128" "cornell-glossy 128x128" "cornell-glass 128x128" "veach-ajar 160x90"; do
    set -- $entry
    scene=$1 res=$2
    runs=""
    for spp in $PT_SPP; do runs="$runs pt:$spp"; done
    runs="$runs bdpt:$BDPT_SPP light:$BDPT_SPP"
    for run in $runs; do
        integrator=${run%%:*} spp=${run##*:}
        a=$(mse "$scene" "$res" "$integrator" "$spp" independent)
        b=$(mse "$scene" "$res" "$integrator" "$spp" sobol)
        python3 -c "print('| $scene | $integrator | $spp | %.4g | %.4g | %.3f |' % ($a, $b, $b / $a))"
    done
done
