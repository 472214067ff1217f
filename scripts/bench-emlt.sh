#!/usr/bin/env bash
# Ensemble MLT's first benchmark (issue 16): `emlt` against `pmlt` at equal mutations per pixel
# (the paper's comparison, Bashford-Rogers et al. 2021 Sec. 5: "equal mutations") on the Cornell
# box and the door scene, SEEDS seeds each, MSE and relMSE (`plexus compare --json`, ε = 0.01)
# against the committed references, wall and process CPU time, acceptance per strategy and emlt's
# guided share from each render's JSON (`integrator_stats`).
#
# Usage: scripts/bench-emlt.sh
# Environment (defaults in brackets):
#   PLEXUS   binary                      [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   MPP      mutations per pixel (--spp of the chain integrators: mpp × pixels mutations in all)  [64]
#   SEEDS    seeds 0 .. SEEDS-1          [5]
#   THREADS  render threads              [2]
#   METHODS  compared integrators        [emlt pmlt]; an entry NAME:KEY=VALUE,KEY=VALUE runs NAME
#            with those settings (--set) under the entry's own label, e.g. emlt:ensemble_size=1024
#   SCENES   scenes with a reference in references/   [cornell-box veach-ajar]
#   OUT      results directory           [docs/bench/emlt]
#   SECTION_OUTS  results directories the docs section is written from, in order   [$OUT]
#            (a probe with other METHODS in its own OUT joins the main table this way)
#
# Every method runs at its defaults (`plexus render --integrator X` would do the same): pmlt's
# portal perturbation is on (weight 2) on veach-ajar, whose scene has a doorway portal; emlt has
# no portal move. Renders are at the reference's resolution (references/S.json: cornell-box
# 128×128, veach-ajar 160×90, half the scenes' films) and its max_depth (8), via `plexus
# reference --resolution`, the command that renders a scene at another resolution; the film
# filter is the scene's own, as for the reference. The methods are interleaved per seed, in an
# order rotated from seed to seed, so a change of the machine's load hits both alike; the 1-minute
# load average before each render is recorded.
#
# Writes OUT/runs.csv (one row per render), OUT/runs.jsonl (the same with the strategy table),
# OUT/machine.txt and the section of docs/benchmarks.md between `<!-- emlt-bench:begin -->` and
# `<!-- emlt-bench:end -->` (scripts/bench_emlt_section.py).
# Cost at the defaults: 20 renders, about 4 CPU minutes on a quiet 2-core machine.
set -euo pipefail
cd "$(dirname "$0")/.."
mpp=${MPP:-64}
seeds=${SEEDS:-5}
threads=${THREADS:-2}
read -r -a methods <<< "${METHODS:-emlt pmlt}"
read -r -a scenes <<< "${SCENES:-cornell-box veach-ajar}"
out=${OUT:-docs/bench/emlt}
source scripts/plexus-binary.sh
plexus_binary bench-emlt
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

load1() { cut -d' ' -f1 /proc/loadavg; }
printf '%s, %s cores, %s GiB; plexus at commit %s; run %s UTC; %s render threads; load average %s when it started\n' \
    "$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)" "$(nproc)" \
    "$(awk '/MemTotal/ {printf "%.0f", $2 / 1048576}' /proc/meminfo)" \
    "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" "$(date -u '+%Y-%m-%d %H:%M')" "$threads" "$(load1)" \
    > "$out/machine.txt"

: > "$out/runs.jsonl"
count=${#methods[@]}
for scene in "${scenes[@]}"; do
    read -r res depth < <(python3 -c "import json; r = json.load(open('references/$scene.json')); print('%dx%d' % tuple(r['resolution']), r['settings']['max_depth'])")
    for seed in $(seq 0 $((seeds - 1))); do
        for i in $(seq 0 $((count - 1))); do
            method=${methods[$(((i + seed) % count))]}
            integrator=${method%%:*} sets=()
            if [[ $method == *:* ]]; then
                IFS=, read -r -a pairs <<< "${method#*:}"
                for pair in "${pairs[@]}"; do sets+=(--set "$pair"); done
            fi
            image="$tmp/$scene-${method//[:=,]/_}-$seed.exr"
            before=$(load1)
            /usr/bin/time -f '%U %S %e' -o "$tmp/time" "$plexus" reference "scenes/$scene.toml" \
                --integrator "$integrator" "${sets[@]}" --spp "$mpp" --seed "$seed" --threads "$threads" \
                --resolution "$res" --set "max_depth=$depth" --out "$image" 2> "$tmp/log" ||
                { cat "$tmp/log" >&2; exit 1; }
            "$plexus" compare --json "$image" "references/$scene.exr" > "$tmp/compare.json"
            python3 - "$scene" "$method" "$seed" "$before" "$tmp/time" "${image%.exr}.json" "$tmp/compare.json" \
                >> "$out/runs.jsonl" <<'PY'
import json, sys
scene, method, seed, load, time_file, render_file, compare_file = sys.argv[1:]
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
    "acceptance": stats["acceptance"], "guided_share": ensemble.get("guided_share"),
    "strategies": [{"name": s["name"], "selected": s["selected"], "acceptance": s["acceptance"]}
                   for s in stats["strategies"]],
    "warnings": stats.get("warnings", []),
}))
PY
            echo "$scene seed $seed $method: $(tail -n 1 "$out/runs.jsonl" | cut -c 1-220)" >&2
        done
    done
done

read -r -a section_outs <<< "${SECTION_OUTS:-$out}"
python3 scripts/bench_emlt_section.py docs/benchmarks.md "${section_outs[@]}"
