#!/usr/bin/env bash
# MMLT and RJMLT brightness stability on the shipped Cornell box (issue 20): SEEDS renders at the
# issue's budget (256×256, max_depth 16, 64 mutations per pixel, 2 threads), and per method the
# image mean's relative standard deviation over the seeds (target ≤ 0.3%: frames of an animation
# must not flicker), split into b's part (the luminance Σ_d n_d·b_d, which expected-value splatting
# makes the image's mean luminance exactly) and the chains' (the image's colour: RGB mean ÷
# luminance), the bootstrap's wall time, mutations per second of chain time (wall minus bootstrap),
# the process's CPU seconds, and each depth's b_d with its relative standard error
# (integrator_stats.per_depth[].b_bootstrap_relative_se), as Markdown.
#
# Usage: docs/lab/scripts/bench-mlt-brightness.sh [SEEDS] [METHODS]     (defaults 20, "mmlt rjmlt")
# Environment: PLEXUS (binary), SPP [64], THREADS [2], OUTDIR [/tmp/bench-mlt-brightness], SET [none].
set -euo pipefail
seeds=${1:-20}
methods=${2:-mmlt rjmlt}
spp=${SPP:-64}
threads=${THREADS:-2}
outdir=${OUTDIR:-/tmp/bench-mlt-brightness}
# SET: further integrator settings, space-separated KEY=VALUE (e.g. SET="progressive_b=false").
extra=()
for kv in ${SET:-}; do
    extra+=(--set "$kv")
done
source "$(dirname "$0")/../../../scripts/plexus-binary.sh"
plexus_binary bench-mlt-brightness scenes/cornell-box.toml
mkdir -p "$outdir"
# Seeds outer, methods inner: a load change hits both methods alike, and a partial run covers both.
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
for seed in $(seq 1 "$seeds"); do
    for method in $methods; do
        "$plexus" render scenes/cornell-box.toml --integrator "$method" --spp "$spp" --threads "$threads" \
            --seed "$seed" --set max_depth=16 "${extra[@]}" -o "$outdir/$method-$seed.exr" >/dev/null 2>&1
    done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
python3 - "$outdir" "$seeds" $methods <<'EOF'
import json, math, statistics, sys
outdir, seeds, methods = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
print("| method | seeds | image mean (mean over seeds) | relative SD of the image mean | of its luminance Σ n_d b_d | of RGB mean ÷ luminance | relative SD of the bootstrap's Σ n_d b_d | bootstrap s | mutations/s of chain time | CPU s | wall s |")
print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
per_depth = {}
rsd = lambda v: f"{100 * statistics.stdev(v) / statistics.mean(v):.3f}%"
for m in methods:
    means, lums, boot, rate, wall, cpu, boot_total = [], [], [], [], [], [], []
    for s in range(1, seeds + 1):
        j = json.load(open(f"{outdir}/{m}-{s}.json"))
        r, g, b = j["image_mean"]
        means.append((r + g + b) / 3)
        lums.append(0.2126 * r + 0.7152 * g + 0.0722 * b)
        st = j["integrator_stats"]
        boot.append(st["bootstrap_seconds"])
        rate.append(st["mutations"] / max(j["wall_time_s"] - st["bootstrap_seconds"], 1e-9))
        wall.append(j["wall_time_s"])
        cpu.append(j.get("cpu_time_s", float("nan")))
        pd = st["per_depth"]
        boot_total.append(sum((1 if d["depth"] == 0 else d["depth"] + 2) * d["b_bootstrap"] for d in pd))
        if s == 1:
            per_depth[m] = st["per_depth"]
    colour = [a / b for a, b in zip(means, lums)]
    print(f"| {m} | {seeds} | {statistics.mean(means):.5g} | {rsd(means)} | {rsd(lums)} | {rsd(colour)} | "
          f"{rsd(boot_total)} | {statistics.median(boot):.2f} | {statistics.median(rate):.3g} | "
          f"{statistics.median(cpu):.1f} | {statistics.median(wall):.1f} |")
for m, depths in per_depth.items():
    total = sum(d["b_bootstrap"] for d in depths) or 1.0
    print(f"\n{m}, seed 1: per depth b_d (bootstrap), its share of Σb, its relative standard error\n")
    print("| depth | b_d | share | relative SE |")
    print("| --- | --- | --- | --- |")
    for d in depths:
        rse = d.get("b_bootstrap_relative_se")
        print(f"| {d['depth']} | {d['b_bootstrap']:.4g} | {100 * d['b_bootstrap'] / total:.1f}% | "
              f"{'—' if rse is None else f'{100 * rse:.2f}%'} |")
EOF
