#!/usr/bin/env bash
# emlt and the unit of length: the Cornell box in millimetres (scenes/cornell-box.toml) and the same
# box in metres (scenes/cornell-box-metres.toml, docs/lab/scripts/scale_scene.py × 0.001) render the
# same image, so a method whose kernels do not depend on the unit has the same MSE on both. Renders
# emlt on both at 128×128, max_depth 8, MPP mutations per pixel, seeds FIRST_SEED ..
# FIRST_SEED+SEEDS−1 (the two scenes interleaved per seed), compares each with
# references/cornell-box.exr (`plexus compare --json`) and prints, per scene, MSE and relMSE
# (mean ± standard error), the mm/m ratio of the mean MSEs, whether it is within 15 %, and emlt's
# α statistics of the linear kernels (integrator_stats.ensemble.guided: mean α and the histogram of
# α between α_s and α_l in fifths, summed over strategies and seeds).
#
# Environment (defaults in brackets):
#   PLEXUS   binary   [$CARGO_TARGET_DIR/release/plexus, else target/release/plexus]
#   SEEDS [8]  FIRST_SEED [0]  MPP [64]  THREADS [2]
#   METHOD   integrator and settings, NAME or NAME:KEY=VALUE,KEY=VALUE   [emlt]
#   OUT      results directory (runs.jsonl, one line per render)   [docs/lab/data/emlt-units]
# Cost: 2 × SEEDS renders of about 6 CPU seconds each.
set -euo pipefail
cd "$(dirname "$0")/../../.."
seeds=${SEEDS:-8}
first_seed=${FIRST_SEED:-0}
mpp=${MPP:-64}
threads=${THREADS:-2}
method=${METHOD:-emlt}
out=${OUT:-docs/lab/data/emlt-units}
source scripts/plexus-binary.sh
plexus_binary bench-emlt-units
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
integrator=${method%%:*}
sets=()
if [[ $method == *:* ]]; then
    IFS=, read -r -a pairs <<< "${method#*:}"
    for pair in "${pairs[@]}"; do sets+=(--set "$pair"); done
fi
: > "$out/runs.jsonl"
for seed in $(seq "$first_seed" $((first_seed + seeds - 1))); do
    for scene in cornell-box cornell-box-metres; do
        image="$tmp/$scene-$seed.exr"
        "$plexus" reference "scenes/$scene.toml" --integrator "$integrator" "${sets[@]}" --spp "$mpp" \
            --seed "$seed" --threads "$threads" --resolution 128x128 --set max_depth=8 --out "$image" \
            2> "$tmp/log" || { cat "$tmp/log" >&2; exit 1; }
        "$plexus" compare --json "$image" references/cornell-box.exr > "$tmp/compare.json"
        python3 - "$scene" "$method" "$seed" "${image%.exr}.json" "$tmp/compare.json" >> "$out/runs.jsonl" <<'PY'
import json, sys
scene, method, seed, render_file, compare_file = sys.argv[1:]
render = json.load(open(render_file))
metrics = json.load(open(compare_file))
ensemble = render["integrator_stats"].get("ensemble") or {}
print(json.dumps({
    "scene": scene, "method": method, "seed": int(seed), "mse": metrics["mse"],
    "relmse": metrics["relmse"], "mean_ratio": metrics["mean_ratio"],
    "acceptance": render["integrator_stats"]["acceptance"],
    "guided": [{k: g.get(k) for k in ("name", "guided", "fallback", "alpha_proposals", "alpha_mean",
                                      "alpha_histogram")} for g in ensemble.get("guided", [])],
}))
PY
        echo "$(tail -n 1 "$out/runs.jsonl" | cut -c 1-160)" >&2
    done
done
python3 - "$out/runs.jsonl" <<'PY'
import json, statistics, sys
runs = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
def summary(values):
    m = statistics.mean(values)
    se = statistics.stdev(values) / len(values) ** 0.5 if len(values) > 1 else 0.0
    return m, se
mean = {}
for scene in ("cornell-box", "cornell-box-metres"):
    rs = [r for r in runs if r["scene"] == scene]
    mse, mse_se = summary([r["mse"] for r in rs])
    rel, rel_se = summary([r["relmse"] for r in rs])
    acc, _ = summary([r["acceptance"] for r in rs])
    mean[scene] = mse
    n = sum(g["alpha_proposals"] or 0 for r in rs for g in r["guided"])
    alpha = sum((g["alpha_mean"] or 0) * (g["alpha_proposals"] or 0) for r in rs for g in r["guided"]) / max(n, 1)
    hist = [sum((g["alpha_histogram"] or [0] * 5)[b] for r in rs for g in r["guided"]) for b in range(5)]
    share = " ".join(f"{h / max(n, 1):.3f}" for h in hist)
    print(f"{scene:20s} {len(rs)} seeds  MSE {mse:.5f} ± {mse_se:.5f}  relMSE {rel:.4f} ± {rel_se:.4f}  "
          f"acceptance {acc:.3f}  α mean {alpha:.3f} over {n} proposals, α_s→α_l fifths {share}")
ratio = mean["cornell-box"] / mean["cornell-box-metres"]
print(f"MSE mm / m = {ratio:.3f}: {'within' if abs(ratio - 1) <= 0.15 else 'NOT within'} 15 %")
PY
