#!/usr/bin/env bash
# The portal perturbation's benchmark (issue 15; the portal paper's Sec. 5 and Fig. 4): pmlt with
# and without the portal perturbation at equal time, relative RMSE against the committed
# references over several seeds, and chain 0's image-plane trace with the integrated
# autocorrelation time of its raster y on portal-planes.
#
# Configurations (the paper's): "MLT" = bidirectional 1/2 + local 1/2; "Ours" = bidirectional 1/2
# + the local half split between the local perturbation and the portal perturbation. With
# LENS=1 the local perturbation is Veach's lens perturbation (issue 14's `lens` weight, from the
# perturb branch); with LENS=0 (default until it is merged) there is no local perturbation in
# "MLT" (bidirectional alone) and "Ours" is bidirectional 1/2 + portal 1/2.
#
# Usage: scripts/bench-portals.sh
# Environment (defaults in brackets):
#   PLEXUS   binary                      [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   TIME     seconds per render          [20]
#   SEEDS    number of seeds             [5]
#   THREADS  render threads              [2]
#   LENS     include the lens perturbation (1) or not (0) [0]
#   SCENES   scene names with a reference in references/ [portal-planes veach-ajar]
#   TRACE    mutations of the trace (every 500th point kept) [250000]
#   OUTDIR   images, JSON, CSV           [/tmp/bench-portals]
# Prints a Markdown table (mean rRMSE over the seeds ± its standard error, and the ratio) and
# the traces' τ_y.
set -euo pipefail
cd "$(dirname "$0")/.."
time_budget=${TIME:-20}
seeds=${SEEDS:-5}
threads=${THREADS:-2}
lens=${LENS:-0}
scenes=${SCENES:-portal-planes veach-ajar}
trace_mutations=${TRACE:-250000}
outdir=${OUTDIR:-/tmp/bench-portals}
source scripts/plexus-binary.sh
plexus_binary bench-portals scenes/portal-planes.toml
mkdir -p "$outdir"
cargo build --release --quiet --example pmlt-trace
trace_bin="${CARGO_TARGET_DIR:-target}/release/examples/pmlt-trace"

if [[ "$lens" == 1 ]]; then
    mlt=(--set bidirectional=2.0 --set lens=2.0 --set portal=0.0)
    ours=(--set bidirectional=2.0 --set lens=1.0 --set portal=1.0)
    mlt_trace=(bidirectional=2.0 lens=2.0 portal=0.0)
    ours_trace=(bidirectional=2.0 lens=1.0 portal=1.0)
else
    mlt=(--set bidirectional=1.0 --set portal=0.0)
    ours=(--set bidirectional=1.0 --set portal=1.0)
    mlt_trace=(bidirectional=1.0 portal=0.0)
    ours_trace=(bidirectional=1.0 portal=1.0)
fi

# A scene at its reference's resolution: a copy beside the original (mesh paths stay valid).
scene_at_reference() {
    local name=$1
    local res
    res=$(python3 -c "import json; r=json.load(open('references/$name.json'))['resolution']; print(f'[{r[0]}, {r[1]}]')")
    local copy="scenes/.bench-portals-$name.toml"
    sed "s/^resolution = .*/resolution = $res/" "scenes/$name.toml" > "$copy"
    echo "$copy"
}

echo "| scene | config | rRMSE (mean ± s.e., $seeds seeds, ${time_budget} s each) | mutations/s |"
echo "| --- | --- | --- | --- |"
for name in $scenes; do
    scene=$(scene_at_reference "$name")
    for config in mlt ours; do
        declare -n sets=$config
        errors=()
        rates=()
        for seed in $(seq 1 "$seeds"); do
            out="$outdir/$name-$config-$seed.exr"
            nice "$plexus" render "$scene" --integrator pmlt --time "$time_budget" --threads "$threads" \
                --seed "$seed" "${sets[@]}" --out "$out" >/dev/null 2>&1
            errors+=("$("$plexus" compare "$out" "references/$name.exr" --json |
                python3 -c "import json,sys,math; print(math.sqrt(json.load(sys.stdin)['relmse']))")")
            rates+=("$(python3 -c "import json; d=json.load(open('${out%.exr}.json')); print(d['samples']/d['wall_time_s'])")")
        done
        python3 - "$name" "$config" "${errors[*]}" "${rates[*]}" <<'PY'
import sys, statistics as st
name, config, errors, rates = sys.argv[1], sys.argv[2], [float(x) for x in sys.argv[3].split()], [float(x) for x in sys.argv[4].split()]
se = st.stdev(errors) / len(errors) ** 0.5 if len(errors) > 1 else float("nan")
print(f"| {name} | {config} | {st.mean(errors):.4f} ± {se:.4f} | {st.mean(rates):.3g} |")
PY
    done
    rm -f "$scene"
done

echo
echo "Image-plane traces on portal-planes (chain 0, one point per 500 mutations; $outdir/trace-*.csv):"
for config in mlt ours; do
    declare -n args=${config}_trace
    printf '%s: ' "$config"
    nice "$trace_bin" scenes/portal-planes.toml 1 "$trace_mutations" 500 "$outdir/trace-$config.csv" \
        bootstrap=20000 "${args[@]}"
done
python3 scripts/portal_trace_svg.py "$outdir/portal-trace.svg" "MLT=$outdir/trace-mlt.csv" "Ours=$outdir/trace-ours.csv"
echo "trace plot: $outdir/portal-trace.svg"
