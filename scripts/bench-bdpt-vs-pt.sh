#!/usr/bin/env bash
# Throughput of the path tracer, BDPT and the light tracer on one scene (default: the Cornell box
# at its 256×256): one render each with a sample budget, printing wall time, samples/s and rays/s
# (closest-hit + shadow queries) from the stats JSON the renderer writes. A sample is a camera
# path per pixel (pt, bdpt) or a light path (light). Wall-clock figures depend on the machine and
# its load: state both with the numbers (e.g. "2 cores, otherwise idle").
#
# Usage: scripts/bench-bdpt-vs-pt.sh [SCENE]
# Environment (defaults in brackets):
#   PLEXUS     binary                  [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   THREADS    render threads          [all cores]
#   SEED       seed                    [1]
#   PT_SPP     pt samples per pixel    [64]
#   BDPT_SPP   bdpt samples per pixel  [16]
#   LIGHT_SPP  light paths per pixel   [64]
#   OUTDIR     where images and JSON go [/tmp/bench-bdpt-vs-pt]
set -euo pipefail

scene=${1:-scenes/cornell-box.toml}
threads=${THREADS:-$(nproc)}
seed=${SEED:-1}
outdir=${OUTDIR:-/tmp/bench-bdpt-vs-pt}
source "$(dirname "$0")/plexus-binary.sh"
plexus_binary bench-bdpt-vs-pt "$scene"
mkdir -p "$outdir"

echo "| integrator | spp | threads | wall s | samples/s | Mrays/s | rays | shadow rays |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for entry in "pt:${PT_SPP:-64}" "bdpt:${BDPT_SPP:-16}" "light:${LIGHT_SPP:-64}"; do
    name=${entry%%:*}
    spp=${entry#*:}
    out="$outdir/$name.exr"
    CI=true "$plexus" render "$scene" --integrator "$name" --spp "$spp" --threads "$threads" --seed "$seed" \
        --set max_depth=16 --out "$out" >"$outdir/$name.log" 2>&1 || { cat "$outdir/$name.log" >&2; exit 1; }
    python3 - "$outdir/$name.json" "$name" "$spp" "$threads" <<'PY'
import json, sys
path, name, spp, threads = sys.argv[1:]
s = json.load(open(path))
c = s["counters"]
print(f"| {name} | {spp} | {threads} | {s['wall_time_s']:.2f} | {s['samples_per_s']:.0f} | "
      f"{s['rays_per_s'] / 1e6:.2f} | {c['rays']} | {c['shadow_rays']} |")
PY
done
