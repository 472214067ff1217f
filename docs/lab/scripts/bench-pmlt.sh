#!/usr/bin/env bash
# Path-space MLT's benchmark (issues 13 and 14): `pmlt` against pt, bdpt, mmlt and rjmlt at equal
# wall time on the four benchmark scenes (3 seeds), MSE and relMSE against the committed references
# (references/, scripts/make-references.sh), and pmlt's per-strategy acceptance on the glass and
# door scenes from its render JSON (`integrator_stats.strategies`).
#
# Usage: docs/lab/scripts/bench-pmlt.sh
# Environment (defaults in brackets):
#   PLEXUS       binary                    [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   TIME         seconds per render on the Cornell scenes   [12]
#   DOOR_TIME    seconds per render on veach-ajar           [20] (MLT start-up needs longer there)
#   SEEDS        seeds 0 .. SEEDS-1                          [3]
#   THREADS      render threads                              [2]
#   INTEGRATORS  compared integrators                        [pt bdpt mmlt rjmlt pmlt]
#   SCENES       scene names with a reference in references/ [cornell-box cornell-glossy cornell-glass veach-ajar]
#   ACCEPTANCE   scenes of the acceptance table              [cornell-glass veach-ajar]
#   OUT          results directory                           [docs/lab/data/pmlt]
#   PORTAL_OFF   on scenes with [[portals]] also run pmlt without its portal perturbation, as the
#                integrator `pmlt-noportal` of the tables (1) or not (0)  [1]
#
# Fairness on a shared machine: each render is one `plexus converge` run of one integrator and one
# seed (converge's own renderer, error and CSV), and the integrators are interleaved per seed, in
# an order rotated from seed to seed, so a change of load hits every integrator alike. Each
# render's process CPU time (user + sys, `/usr/bin/time`) and the 1-minute load average before and
# after it are recorded: under load, equal wall time is not equal work, and the CPU column shows
# how unequal it was. On a quiet machine the CPU time is about THREADS × the budget.
#
# Writes OUT/<scene>-converge.{csv,md} (the CSV is converge's format: `plexus converge
# scenes/S.toml --replot OUT/S-converge.csv --out-dir DIR` redraws tables and plot),
# OUT/<scene>-cpu.csv, OUT/<scene>-strategies.json (the acceptance renders' strategy statistics),
# OUT/<scene>-machine.txt, and then the section of docs/lab/benchmarks-history.md between the markers
# `<!-- pmlt-bench:begin -->` and `<!-- pmlt-bench:end -->` (docs/lab/scripts/bench_pmlt_section.py; the
# rest of the page is left as it is). OUT/reading.md (the interpretation) is written by hand and
# must be revisited when the numbers change.
# Cost: 5 integrators × 3 seeds × 3 × 12 s + 6 × 3 × 20 s on the door (with pmlt-noportal) and 9
# acceptance renders ≈ 20 min of wall time.
set -euo pipefail
cd "$(dirname "$0")/../../.."
time_budget=${TIME:-12}
door_time=${DOOR_TIME:-20}
seeds=${SEEDS:-3}
threads=${THREADS:-2}
read -r -a integrators <<< "${INTEGRATORS:-pt bdpt mmlt rjmlt pmlt}"
read -r -a scenes <<< "${SCENES:-cornell-box cornell-glossy cornell-glass veach-ajar}"
acceptance=${ACCEPTANCE:-cornell-glass veach-ajar}
out=${OUT:-docs/lab/data/pmlt}
portal_off=${PORTAL_OFF:-1}
source scripts/plexus-binary.sh
plexus_binary bench-pmlt
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp" scenes/.bench-pmlt-*.toml' EXIT

load1() { cut -d' ' -f1 /proc/loadavg; }
# Where and when a scene's renders ran (one file per scene, so that a rerun of some scenes keeps
# the others' record).
machine() {
    printf '%s, %s cores, %s GiB; plexus at commit %s; run %s UTC; %s render threads; load average %s when it started\n' \
        "$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)" "$(nproc)" \
        "$(awk '/MemTotal/ {printf "%.0f", $2 / 1048576}' /proc/meminfo)" \
        "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" "$(date -u '+%Y-%m-%d %H:%M')" "$threads" "$(load1)"
}

budget_of() { if [[ $1 == veach-ajar ]]; then echo "$door_time"; else echo "$time_budget"; fi; }

# pmlt without the portal perturbation: a copy of the scene beside it (mesh paths stay valid) whose
# [integrator] table is pmlt's with portal = 0 (converge gives the scene's own integrator its table).
noportal_scene() {
    python3 - "scenes/$1.toml" "scenes/.bench-pmlt-$1.toml" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
table = '[integrator]\ntype = "pmlt"\nportal = 0.0\n\n'
text, n = re.subn(r"^\[integrator\]\n(?:(?!\[).*\n)*", table, text, flags=re.M)
if n == 0:
    text += "\n" + table
open(sys.argv[2], "w").write(text)
PY
}

for scene in "${scenes[@]}"; do
    budget=$(budget_of "$scene")
    machine > "$out/$scene-machine.txt"
    csv="$out/$scene-converge.csv"
    cpu="$out/$scene-cpu.csv"
    echo "integrator,seed,budget,wall_time,samples_or_mutations,rays,mse,relmse,nonfinite_dropped" > "$csv"
    echo "integrator,seed,budget,cpu_s,process_wall_s,load1_before,load1_after" > "$cpu"
    runs=("${integrators[@]}")
    if [[ $portal_off == 1 ]] && grep -q '^\[\[portals\]\]' "scenes/$scene.toml"; then
        noportal_scene "$scene"
        runs+=(pmlt-noportal)
    fi
    count=${#runs[@]}
    for seed in $(seq 0 $((seeds - 1))); do
        for i in $(seq 0 $((count - 1))); do
            integ=${runs[$(((i + seed) % count))]}
            dir="$tmp/$scene-$integ-$seed"
            mkdir -p "$dir"
            file="scenes/$scene.toml" name=$integ
            if [[ $integ == pmlt-noportal ]]; then
                file="scenes/.bench-pmlt-$scene.toml" name=pmlt
            fi
            before=$(load1)
            /usr/bin/time -f '%U %S %e' -o "$dir/time" "$plexus" converge "$file" \
                --reference "references/$scene.exr" --integrators "$name" --times "$budget" --seeds 1 \
                --first-seed "$seed" --threads "$threads" --set max_depth=8 --out-dir "$dir" 2> "$dir/log" ||
                { cat "$dir/log" >&2; exit 1; }
            after=$(load1)
            tail -n +2 "$dir/$(basename "$file" .toml)-converge.csv" | sed "s/^pmlt,/$integ,/" >> "$csv"
            read -r user sys wall < "$dir/time"
            echo "$integ,$seed,$budget,$(awk "BEGIN { printf \"%.2f\", $user + $sys }"),$wall,$before,$after" >> "$cpu"
            echo "$scene seed $seed $integ: $(tail -n 1 "$csv"); CPU $user+$sys s; load $before -> $after" >&2
        done
    done
    rm -f "scenes/.bench-pmlt-$scene.toml"
    # The Markdown tables of converge (one budget: its plot would be one point per integrator).
    "$plexus" converge "scenes/$scene.toml" --replot "$csv" --out-dir "$out" 2> /dev/null
    rm -f "$out/$scene-converge.png"
done

# Per-strategy acceptance: pmlt renders with their JSON at the reference's resolution and the same
# budget, one per seed; the strategy statistics of each are kept.
for scene in $acceptance; do
    budget=$(budget_of "$scene")
    res=$(python3 -c "import json; r = json.load(open('references/$scene.json'))['resolution']; print('%dx%d' % tuple(r))")
    for seed in $(seq 0 $((seeds - 1))); do
        "$plexus" reference "scenes/$scene.toml" --integrator pmlt --time "$budget" --seed "$seed" \
            --threads "$threads" --resolution "$res" --set max_depth=8 --out "$tmp/$scene-pmlt-$seed.exr" 2> /dev/null
    done
    variants=(pmlt)
    if [[ $portal_off == 1 ]] && grep -q '^\[\[portals\]\]' "scenes/$scene.toml"; then
        for seed in $(seq 0 $((seeds - 1))); do
            "$plexus" reference "scenes/$scene.toml" --integrator pmlt --time "$budget" --seed "$seed" \
                --threads "$threads" --resolution "$res" --set max_depth=8 --set portal=0 \
                --out "$tmp/$scene-noportal-$seed.exr" 2> /dev/null
        done
        variants+=(noportal)
    fi
    for variant in "${variants[@]}"; do
        target="$out/$scene-strategies.json"
        [[ $variant == noportal ]] && target="$out/$scene-noportal-strategies.json"
        python3 - "$target" "$tmp/$scene-$variant"-*.json <<'PY'
import json, sys
runs = []
for path in sys.argv[2:]:
    with open(path) as f:
        d = json.load(f)
    st = d["integrator_stats"]
    runs.append({"seed": d.get("seed"), "wall_time_s": d.get("wall_time_s"), "samples": d.get("samples"),
                 "strategies": st.get("strategies", []), "warnings": st.get("warnings", [])})
with open(sys.argv[1], "w") as f:
    json.dump(runs, f, indent=1)
PY
    done
done

python3 docs/lab/scripts/bench_pmlt_section.py "$out"
echo "docs/lab/benchmarks-history.md: pmlt section rewritten from $out; revisit $out/reading.md against the new numbers" >&2
