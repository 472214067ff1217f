#!/usr/bin/env bash
# Russian roulette in `pt` before and after issue 12 (survival on the throughput with refraction's
# 1/η² undone, never rolled at throughput >= 1), on the glass Cornell box against its reference, at
# equal time with `plexus converge`. Two binaries: OLD built from the commit before the change,
# NEW from after. Each roulette setting (rr_depth) runs the two binaries one after the other, so
# they share the machine's load as far as possible.
#
# Besides the converge tables it prints, per binary and rr_depth, the means over seeds and budgets
# of: MSE, samples/s, rays per sample (the cost of a sample, independent of the machine's load)
# and MSE × rays (∝ variance per ray traced: the equal-cost figure that load cannot skew, since
# MSE ∝ variance per sample / samples).
#
# Usage: OLD=/path/to/old/plexus NEW=/path/to/new/plexus docs/lab/scripts/bench-roulette.sh
# Environment (defaults in brackets):
#   TIMES       budgets in seconds          [3,6]
#   SEEDS       seeds per budget            [3]
#   RR_DEPTHS   rr_depth values to compare  ["5 2"] (5 is the default; 2 rolls more vertices)
#   OUTDIR      where CSVs and tables go    [/tmp/bench-roulette]
# ~ 2 × |RR_DEPTHS| × SEEDS × Σ TIMES seconds (defaults: 108 s).
set -euo pipefail
cd "$(dirname "$0")/../../.."
: "${OLD:?set OLD to the binary built before the change}"
: "${NEW:?set NEW to the binary built after the change}"
times=${TIMES:-3,6}
seeds=${SEEDS:-3}
rr_depths=${RR_DEPTHS:-5 2}
outdir=${OUTDIR:-/tmp/bench-roulette}
scene=scenes/cornell-glass
printf '%s, %s cores; load average %s at start; %s\n' \
    "$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)" "$(nproc)" \
    "$(cut -d' ' -f1-3 /proc/loadavg)" "$(date -u +%Y-%m-%dT%H:%MZ)"
echo
echo "| rr_depth | binary | mean MSE | samples/s | rays/sample | MSE × rays |"
echo "|---:|---|---:|---:|---:|---:|"
for rr in $rr_depths; do
    for which in old new; do
        if [[ $which == old ]]; then bin=$OLD; else bin=$NEW; fi
        dir=$outdir/rr$rr-$which
        mkdir -p "$dir"
        "$bin" converge "$scene.toml" --reference "references/$(basename $scene).exr" --integrators pt \
            --times "$times" --seeds "$seeds" --threads 2 --set max_depth=8 --set rr_depth="$rr" \
            --out-dir "$dir" >"$dir/converge.log" 2>&1
        # integrator,seed,budget,wall_time,samples_or_mutations,rays,mse,relmse,nonfinite_dropped
        awk -F, -v rr="$rr" -v which="$which" 'NR > 1 {
                n++; mse += $7; sps += $5 / $4; rps += $6 / $5; mr += $7 * $6 }
            END { printf "| %s | %s | %.4e | %.0f | %.3f | %.4e |\n", rr, which, mse / n, sps / n, rps / n, mr / n }' \
            "$dir/$(basename $scene)-converge.csv"
    done
done
echo
echo "CSVs and converge tables: $outdir/rr*-{old,new}/"
