#!/usr/bin/env bash
# Ensemble MLT's benchmark: `emlt` against `pmlt` at equal mutations per pixel (the paper's
# comparison, Bashford-Rogers et al. 2021 Sec. 5: "equal mutations") and, with EQUAL_TIME=1, at
# equal CPU time; SEEDS seeds each, MSE and relMSE (`plexus compare --json`, ε = 0.01) against the
# committed references, wall and process CPU time, acceptance per strategy and emlt's guided share
# from each render's JSON (`integrator_stats`).
#
# Usage: docs/lab/scripts/bench-emlt.sh            issue 16's run (box and door, emlt vs pmlt)
#        docs/lab/scripts/bench-emlt.sh part2      issue 17's run: the four scenes, the ablation methods of
#                                         the paper's Table 1 and the equal-time pmlt (the preset
#                                         below; any variable set in the environment overrides it)
# Environment (defaults in brackets):
#   PLEXUS   binary                      [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   MPP      mutations per pixel (--spp of the chain integrators: mpp × pixels mutations in all)  [64]
#   SEEDS    seeds FIRST_SEED .. FIRST_SEED+SEEDS-1 [5]
#   FIRST_SEED  the first seed (a run's seeds can be split over processes this way)   [0]
#   THREADS  render threads              [2]
#   METHODS  compared integrators        [emlt pmlt]; an entry NAME:KEY=VALUE,KEY=VALUE runs NAME
#            with those settings (--set) under the entry's own label, e.g. emlt:ensemble_size=1024
#   SCENES   references in references/ (NAME.exr and NAME.json; the scene is the one the JSON
#            names, rendered at its resolution and max_depth)   [cornell-box veach-ajar]
#   EQUAL_TIME  1: after the equal-mutation renders, `pmlt` again per scene and seed at the
#            mutations per pixel that cost what EQUAL_TIME_TO cost: MPP × the median over seeds
#            of (render CPU of EQUAL_TIME_TO)/(render CPU of pmlt), labelled `pmlt@time`; "only":
#            the equal-time renders alone, appended to OUT's existing runs (an interrupted run's
#            second half, or the equal-time pass of some scenes run beside the others)   [0]
#   EQUAL_TIME_TO  the method label pmlt's time is matched to   [emlt]
#   OUT      results directory           [docs/lab/data/emlt]
#   SECTION  the docs section written: "emlt-bench" (issue 16's table) or "emlt17-bench" (issue
#            17's: MSE ratios at equal mutations and equal time, acceptance change, CPU overhead,
#            the ablation table)   [emlt-bench]
#   SECTION_OUTS  results directories the docs section is written from, in order   [$OUT]
#            (a probe with other METHODS in its own OUT joins the main table this way)
#
# Every method runs at its defaults (`plexus render --integrator X` would do the same): pmlt's
# portal perturbation is on (weight 2) on veach-ajar, whose scene has a doorway portal; emlt has
# no portal move. Renders are at the reference's resolution (references/S.json: cornell-box
# 128×128, veach-ajar 160×90, half the scenes' films; staircase 72×128, breakfast-window 32×32)
# and its max_depth (8), via `plexus reference --resolution`, the command that renders a scene at
# another resolution; the film filter is the scene's own, as for the reference. The methods are
# interleaved per seed, in an order rotated from seed to seed, so a change of the machine's load
# hits both alike; the 1-minute load average before each render is recorded. The CPU of loading
# the scene (one pt render of 1 sample per pixel per scene, `load_cpu_s` in runs.jsonl's first
# line per scene) is subtracted from each render's process CPU for the per-mutation costs.
#
# Writes OUT/runs.csv (one row per render), OUT/runs.jsonl (the same with the strategy table),
# OUT/machine.txt and the section of docs/lab/benchmarks-history.md between `<!-- SECTION:begin -->` and
# `<!-- SECTION:end -->` (docs/lab/scripts/bench_emlt_section.py).
# Cost at the defaults: 20 renders, about 4 CPU minutes on a quiet 2-core machine; part2: 100
# renders, about 15 CPU minutes.
set -euo pipefail
cd "$(dirname "$0")/../../.."
if [[ ${1:-} == part2 ]]; then
    : "${METHODS:=emlt pmlt emlt:perturbations=anisotropic emlt:perturbations=all}"
    : "${SCENES:=cornell-box veach-ajar staircase breakfast-window}"
    : "${EQUAL_TIME:=1}" "${OUT:=docs/lab/data/emlt17}" "${SECTION:=emlt17-bench}"
elif [[ -n ${1:-} ]]; then
    echo "bench-emlt: unknown preset '$1' (the only one is 'part2')" >&2
    exit 1
fi
mpp=${MPP:-64}
seeds=${SEEDS:-5}
first_seed=${FIRST_SEED:-0}
threads=${THREADS:-2}
read -r -a methods <<< "${METHODS:-emlt pmlt}"
read -r -a scenes <<< "${SCENES:-cornell-box veach-ajar}"
out=${OUT:-docs/lab/data/emlt}
equal_time=${EQUAL_TIME:-0}
equal_time_to=${EQUAL_TIME_TO:-emlt}
section=${SECTION:-emlt-bench}
source scripts/plexus-binary.sh
plexus_binary bench-emlt
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

load1() { cut -d' ' -f1 /proc/loadavg; }
machine=$out/machine.txt
if [[ $equal_time == only ]]; then
    machine=$tmp/machine.txt
fi
printf '%s, %s cores, %s GiB; plexus at commit %s; run %s UTC; %s render threads; load average %s when it started\n' \
    "$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)" "$(nproc)" \
    "$(awk '/MemTotal/ {printf "%.0f", $2 / 1048576}' /proc/meminfo)" \
    "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" "$(date -u '+%Y-%m-%d %H:%M')" "$threads" "$(load1)" \
    > "$machine"
if [[ $equal_time == only ]]; then
    printf '%s' "$(cat "$out/machine.txt"); equal-time pass of ${scenes[*]}: $(cat "$machine")" > "$out/machine.txt"
fi

render_one() { # scene seed method mpp label
    local scene=$1 seed=$2 method=$3 spp=$4 label=$5 integrator=${3%%:*} sets=() pairs image before
    if [[ $method == *:* ]]; then
        IFS=, read -r -a pairs <<< "${method#*:}"
        for pair in "${pairs[@]}"; do sets+=(--set "$pair"); done
    fi
    image="$tmp/$scene-${label//[:=,@]/_}-$seed.exr"
    before=$(load1)
    /usr/bin/time -f '%U %S %e' -o "$tmp/time" "$plexus" reference "$scene_file" \
        --integrator "$integrator" "${sets[@]}" --spp "$spp" --seed "$seed" --threads "$threads" \
        --resolution "$res" --set "max_depth=$depth" --out "$image" 2> "$tmp/log" ||
        { cat "$tmp/log" >&2; exit 1; }
    "$plexus" compare --json "$image" "references/$scene.exr" > "$tmp/compare.json"
    python3 - "$scene" "$label" "$seed" "$before" "$tmp/time" "${image%.exr}.json" "$tmp/compare.json" "$load_cpu" \
        >> "$out/runs.jsonl" <<'PY'
import json, sys
scene, method, seed, load, time_file, render_file, compare_file, load_cpu = sys.argv[1:]
user, sys_, wall = map(float, open(time_file).read().split())
render = json.load(open(render_file))
metrics = json.load(open(compare_file))
stats = render["integrator_stats"]
ensemble = stats.get("ensemble") or {}
print(json.dumps({
    "scene": scene, "method": method, "seed": int(seed), "load1_before": float(load),
    "resolution": render["resolution"], "settings": render["settings"],
    "mse": metrics["mse"], "relmse": metrics["relmse"], "mean_ratio": metrics["mean_ratio"],
    "mutations": stats["mutations"], "mutations_per_pixel": stats["mutations_per_pixel"],
    "render_wall_s": render["wall_time_s"], "process_wall_s": wall, "cpu_s": user + sys_,
    "load_cpu_s": float(load_cpu),
    "acceptance": stats["acceptance"], "guided_share": ensemble.get("guided_share"),
    "strategies": [{"name": s["name"], "selected": s["selected"], "acceptance": s["acceptance"]}
                   for s in stats["strategies"]],
    "warnings": stats.get("warnings", []),
}))
PY
    echo "$scene seed $seed $label: $(tail -n 1 "$out/runs.jsonl" | cut -c 1-220)" >&2
}

scene_setup() { # scene: sets scene_file, res, depth and load_cpu (the CPU of loading it)
    read -r scene_file res depth < <(python3 -c "import json; r = json.load(open('references/$1.json')); print(r['scene'], '%dx%d' % tuple(r['resolution']), r['settings']['max_depth'])")
    /usr/bin/time -f '%U %S' -o "$tmp/time" "$plexus" reference "$scene_file" --integrator pt --spp 1 \
        --seed 0 --threads "$threads" --resolution "$res" --set "max_depth=$depth" --out "$tmp/load.exr" 2> "$tmp/log" ||
        { cat "$tmp/log" >&2; exit 1; }
    load_cpu=$(awk '{print $1 + $2}' "$tmp/time")
}

if [[ $equal_time != only ]]; then
    : > "$out/runs.jsonl"
    count=${#methods[@]}
    for scene in "${scenes[@]}"; do
        scene_setup "$scene"
        for seed in $(seq "$first_seed" $((first_seed + seeds - 1))); do
            for i in $(seq 0 $((count - 1))); do
                method=${methods[$(((i + seed) % count))]}
                render_one "$scene" "$seed" "$method" "$mpp" "$method"
            done
        done
    done
fi

# Equal time: pmlt at the mutations per pixel that cost what EQUAL_TIME_TO cost per scene.
if [[ $equal_time == 1 || $equal_time == only ]]; then
    for scene in "${scenes[@]}"; do
        scene_setup "$scene"
        time_mpp=$(python3 - "$out/runs.jsonl" "$scene" "$equal_time_to" "$mpp" <<'PY'
import json, statistics, sys
runs_file, scene, target, mpp = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
runs = [json.loads(line) for line in open(runs_file) if line.strip()]
def cpu(label):
    return statistics.median(r["cpu_s"] - r["load_cpu_s"] for r in runs if r["scene"] == scene and r["method"] == label)
print(max(1, round(mpp * cpu(target) / cpu("pmlt"))))
PY
)
        echo "$scene: pmlt at $time_mpp mutations per pixel costs what $equal_time_to costs at $mpp" >&2
        for seed in $(seq "$first_seed" $((first_seed + seeds - 1))); do
            render_one "$scene" "$seed" pmlt "$time_mpp" "pmlt@time"
        done
    done
fi

read -r -a section_outs <<< "${SECTION_OUTS:-$out}"
python3 docs/lab/scripts/bench_emlt_section.py --section "$section" --equal-time-to "$equal_time_to" docs/lab/benchmarks-history.md "${section_outs[@]}"
