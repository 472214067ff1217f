#!/usr/bin/env bash
# PSSMLT, MMLT and RJMLT on the door scene (scenes/veach-ajar.toml) at an equal time budget, one
# render each with the same seed and thread count; prints Markdown tables of the statistics the
# renderer writes to <out>.json (integrator_stats): mutations, mutations/s, acceptance, effective
# path ratio (technique paths with a non-zero contribution over technique paths evaluated; MMLT
# paper, Sec. 5: 11.81% PSSMLT against 29.75% MMLT), the fraction of proposals with a non-zero
# contribution, bootstrap time; MMLT's technique share per depth; and the acceptance per depth of
# RJMLT's small steps, MMLT's technique-changing small steps and RJMLT's jumps (RJMLT paper, Fig. 4).
#
# Usage: scripts/bench-mlt.sh [SCENE]
# Environment (defaults in brackets):
#   PLEXUS     binary              [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   TIME       seconds per method  [60]
#   THREADS    render threads      [2]
#   SEED       seed                [1]
#   BOOTSTRAP  bootstrap paths per depth, passed as --set bootstrap=N [unset: the default 100000]
#   OUTDIR     where images and JSON go [/tmp/bench-mlt]
set -euo pipefail

scene=${1:-scenes/veach-ajar.toml}
time_budget=${TIME:-60}
threads=${THREADS:-2}
seed=${SEED:-1}
outdir=${OUTDIR:-/tmp/bench-mlt}
source "$(dirname "$0")/plexus-binary.sh"
plexus_binary bench-mlt "$scene"
mkdir -p "$outdir"

extra=()
if [[ -n "${BOOTSTRAP:-}" ]]; then
    extra+=(--set "bootstrap=$BOOTSTRAP")
fi

for method in pssmlt mmlt rjmlt; do
    cmd=("$plexus" render "$scene" --integrator "$method" --time "$time_budget" --threads "$threads"
        --seed "$seed" --out "$outdir/$method.exr" "${extra[@]}")
    echo "bench-mlt: ${cmd[*]}" >&2
    "${cmd[@]}" >&2
done

python3 - "$outdir" <<'PY'
import json, sys, os

outdir = sys.argv[1]
docs = {}
for method in ("pssmlt", "mmlt", "rjmlt"):
    with open(os.path.join(outdir, method + ".json")) as f:
        docs[method] = json.load(f)
    st = docs[method].get("integrator_stats", {})
    if "mutations" not in st:
        # A black scene (no bootstrap path carried light) stops after the bootstrap.
        sys.exit("bench-mlt: %s rendered no chains: %s" % (method, "; ".join(st.get("warnings", []))))

def pct(x):
    return "—" if x is None else "%.1f%%" % (100.0 * x)

print("| method | mutations | mutations/s | acceptance | effective path ratio (all; large / small / jump) | non-zero proposals | bootstrap (paths/depth, s) | wall time |")
print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for method, doc in docs.items():
    st = doc["integrator_stats"]
    muts, boot, wall = st["mutations"], st["bootstrap_seconds"], doc.get("wall_time_s")
    # Mutations per second of chain time: the render's wall time minus the bootstrap.
    chain_s = (wall - boot) if isinstance(wall, (int, float)) and wall > boot else None
    rate = muts / chain_s if chain_s else float("nan")
    moves = st["moves"]
    per_move = " / ".join(pct((moves.get(k) or {}).get("effective_path_ratio")) for k in ("large", "small", "jump"))
    print("| %s | %d | %.3g | %s | %s; %s | %s | %s, %.2f s | %.1f s |" % (method.upper(), muts, rate, pct(st["acceptance"]),
          pct(st["effective_path_ratio"]), per_move, pct(st["nonzero_proposal_ratio"]), st.get("bootstrap_paths_per_depth"),
          boot, wall))
print()
print("MMLT per depth (d = scattering events; technique share = fraction of iterations the state used (s, t)):")
print()
print("| depth | iterations | b (bootstrap) | b (final) | acceptance | technique share |")
print("| ---: | ---: | ---: | ---: | ---: | --- |")
for d in docs["mmlt"]["integrator_stats"]["per_depth"]:
    counts = d.get("technique_state_counts") or []
    total = sum(c["iterations"] for c in counts) or 1
    parts = ", ".join("s%d t%d %.1f%%" % (c["s"], c["t"], 100.0 * c["iterations"] / total) for c in counts)
    print("| %s | %d | %.3g | %.3g | %s | %s |" % (d["depth"], d["iterations"], d["b_bootstrap"], d["b"], pct(d["acceptance"]), parts))
print()
print("Acceptance per path depth (RJMLT paper, Fig. 4; see scripts/fig4_table.py):")
print()
PY
python3 "$(dirname "$0")/fig4_table.py" "$outdir/mmlt.json" "$outdir/rjmlt.json"
