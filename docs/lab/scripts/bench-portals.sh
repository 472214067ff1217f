#!/usr/bin/env bash
# The portal perturbation's benchmark (issue 15; the portal paper's Sec. 5–6, Fig. 4, 5 and 8):
# pmlt with and without the portal perturbation at equal time, relative RMSE against the committed
# references over several seeds, and chain 0's image-plane trace with the integrated
# autocorrelation time of its raster y on portal-planes.
#
# Configurations (the paper's): "MLT" = bidirectional 1/2 + lens perturbation 1/2; "Ours" =
# bidirectional 1/2 + the local half split between the lens and the portal perturbation (1/4
# each on a path that crosses a portal; pmlt shares a perturbation weight among the suitable
# perturbations, so the weights are bidirectional 2, lens 2, portal 2; on a path that crosses no
# portal "Ours" is "MLT"). The caustic and multi-chain perturbations are off in both.
#
# The machine may be shared: the renders are interleaved (for each seed, each scene, MLT then
# Ours) so that both configurations see the same load, and the 1-minute load average is recorded
# before every render (its median and range are printed).
#
# Usage: docs/lab/scripts/bench-portals.sh
# Environment (defaults in brackets):
#   PLEXUS   binary                      [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   TIME     seconds per render          [20]
#   SEEDS    number of seeds             [5]
#   THREADS  render threads              [2]
#   SCENES   scene names with a reference in references/ [portal-planes breakfast-window veach-ajar]
#   TRACE    mutations of the trace (every EVERY-th point kept) [250000]
#   EVERY    trace spacing in mutations  [50]
#   BOOTSTRAP pmlt bootstrap paths (both configurations; part of each render's time) [20000]
#   OUTDIR   images, JSON, CSV           [/tmp/bench-portals]
# Prints a Markdown table (mean rRMSE over the seeds ± its standard error, the ratio Ours/MLT with
# the standard error of the per-seed difference) and the traces' τ_y.
set -euo pipefail
cd "$(dirname "$0")/../../.."
time_budget=${TIME:-20}
seeds=${SEEDS:-5}
threads=${THREADS:-2}
scenes=${SCENES:-portal-planes breakfast-window veach-ajar}
trace_mutations=${TRACE:-250000}
every=${EVERY:-50}
bootstrap=${BOOTSTRAP:-20000}
outdir=${OUTDIR:-/tmp/bench-portals}
source scripts/plexus-binary.sh
plexus_binary bench-portals scenes/portal-planes.toml
mkdir -p "$outdir"
cargo build --release --quiet --example pmlt-trace
trace_bin="${CARGO_TARGET_DIR:-target}/release/examples/pmlt-trace"

common=(bidirectional=2.0 lens=2.0 caustic=0.0 multi_chain=0.0 bootstrap=$bootstrap)
mlt_set=("${common[@]}" portal=0.0)
ours_set=("${common[@]}" portal=2.0)
set_flags() { for kv in "$@"; do printf -- '--set\n%s\n' "$kv"; done; }
mapfile -t mlt < <(set_flags "${mlt_set[@]}")
mapfile -t ours < <(set_flags "${ours_set[@]}")

# A scene at its reference's resolution: a copy beside the original (mesh paths stay valid).
scene_at_reference() {
    local name=$1
    local res
    res=$(python3 -c "import json; r=json.load(open('references/$name.json'))['resolution']; print(f'[{r[0]}, {r[1]}]')")
    local copy="scenes/.bench-portals-$name.toml"
    sed "s/^resolution = .*/resolution = $res/" "scenes/$name.toml" > "$copy"
    echo "$copy"
}

results="$outdir/results.tsv"
: > "$results"
for name in $scenes; do scene_at_reference "$name" >/dev/null; done
trap 'for name in $scenes; do rm -f "scenes/.bench-portals-$name.toml"; done' EXIT
for seed in $(seq 1 "$seeds"); do
    for name in $scenes; do
        scene="scenes/.bench-portals-$name.toml"
        for config in mlt ours; do
            declare -n sets=$config
            out="$outdir/$name-$config-$seed.exr"
            load=$(cut -d' ' -f1 /proc/loadavg)
            nice "$plexus" render "$scene" --integrator pmlt --time "$time_budget" --threads "$threads" \
                --seed "$seed" "${sets[@]}" --out "$out" >/dev/null 2>&1
            error=$("$plexus" compare "$out" "references/$name.exr" --json |
                python3 -c "import json,sys,math; print(math.sqrt(json.load(sys.stdin)['relmse']))")
            rate=$(python3 -c "import json; d=json.load(open('${out%.exr}.json')); print(d['samples']/d['wall_time_s'])")
            printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$config" "$seed" "$error" "$rate" "$load" >> "$results"
        done
    done
done

python3 - "$results" "$seeds" "$time_budget" <<'PY'
import sys, statistics as st
rows = [l.split("\t") for l in open(sys.argv[1]).read().splitlines()]
seeds, budget = sys.argv[2], sys.argv[3]
loads = [float(r[5]) for r in rows]
print(f"load average (1 min) before the renders: median {st.median(loads):.1f}, range {min(loads):.1f}–{max(loads):.1f}")
print()
print(f"| scene | MLT (bidirectional + lens) | Ours (+ portal) | Ours / MLT | mutations/s MLT, Ours |")
print("| --- | ---: | ---: | ---: | ---: |")
for name in dict.fromkeys(r[0] for r in rows):
    by = {c: {int(r[2]): (float(r[3]), float(r[4])) for r in rows if r[0] == name and r[1] == c} for c in ("mlt", "ours")}
    common = sorted(set(by["mlt"]) & set(by["ours"]))
    def stat(c):
        e = [by[c][s][0] for s in common]
        return st.mean(e), (st.stdev(e) / len(e) ** 0.5 if len(e) > 1 else float("nan"))
    (m, sm), (o, so) = stat("mlt"), stat("ours")
    d = [by["ours"][s][0] - by["mlt"][s][0] for s in common]
    sd = st.stdev(d) / len(d) ** 0.5 if len(d) > 1 else float("nan")
    rate = lambda c: st.mean(by[c][s][1] for s in common)
    print(f"| {name} | {m:.4f} ± {sm:.4f} | {o:.4f} ± {so:.4f} | {o / m:.2f} (difference {o - m:+.4f} ± {sd:.4f}) | "
          f"{rate('mlt'):.3g}, {rate('ours'):.3g} |")
print(f"\n({len(common)} seeds, {budget} s per render, rRMSE = sqrt(relMSE) of plexus compare)")
PY

echo
echo "Image-plane traces on portal-planes (chain 0, one point per $every mutations; $outdir/trace-*.csv):"
for config in mlt ours; do
    declare -n args=${config}_set
    printf '%s: ' "$config"
    nice "$trace_bin" scenes/portal-planes.toml 1 "$trace_mutations" "$every" "$outdir/trace-$config.csv" \
        "${args[@]}"
done
python3 docs/lab/scripts/portal_trace_svg.py "$outdir/portal-trace.svg" "MLT=$outdir/trace-mlt.csv" "Ours=$outdir/trace-ours.csv"
echo "trace plot: $outdir/portal-trace.svg"
