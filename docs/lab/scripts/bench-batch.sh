#!/usr/bin/env bash
# plexus-batch scaling on this machine (docs/batch.md, "Scaling on this machine"): the same batch
# on a LocalCluster of 1 and of 2 workers, its wall time, the workers' time, the merges' share,
# and whether the images are the same bytes.
#
#   docs/lab/scripts/bench-batch.sh [BATCH.toml]      (default: python/examples/cornell.toml)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
BATCH="$(realpath "${1:-$ROOT/python/examples/cornell.toml}")"
OUT="$(mktemp -d "${TMPDIR:-/tmp}/plexus-bench-batch.XXXXXX")"
trap 'rm -rf "$OUT"' EXIT

for workers in 1 2; do
    # CPU seconds of the whole run (plexus-batch, the cluster's processes, every plexus run): on a
    # loaded machine the wall times say little, these what the batch cost.
    python3 -c '
import os, subprocess, sys
r = subprocess.run(sys.argv[2:])
t = os.times()
open(sys.argv[1], "w").write(str(t.children_user + t.children_system))
sys.exit(r.returncode)' "$OUT/cpu-$workers" \
        "$ROOT/dev" batch "$BATCH" --workers "$workers" --quiet --summary "$OUT/summary-$workers.json" >/dev/null
    mkdir -p "$OUT/images-$workers"
    python3 - "$OUT/summary-$workers.json" "$OUT/images-$workers" <<'PY'
import json, shutil, sys
for job in json.load(open(sys.argv[1]))["jobs"]:
    for o in job["outputs"]:
        if o.endswith(".png"):
            shutil.copy(o, sys.argv[2])
PY
done

python3 - "$OUT" <<'PY'
import filecmp, json, os, sys
print(f"load average (1 min) at the end: {os.getloadavg()[0]:.1f}")
out = sys.argv[1]
rows = {w: json.load(open(f"{out}/summary-{w}.json")) for w in (1, 2)}
pngs = sorted(os.listdir(f"{out}/images-1"))
same = all(filecmp.cmp(f"{out}/images-1/{p}", f"{out}/images-2/{p}", shallow=False) for p in pngs)
print("| workers | batch wall s | speed-up | CPU s (all processes) | worker s (shards + merges) | merges s | merges / worker time |")
print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for w, s in rows.items():
    assert s["ok"], f"the {w}-worker run failed"
    worker = sum(j["worker_s"] for j in s["jobs"])
    merge = sum(j["merge_s"] for j in s["jobs"])
    speedup = rows[1]["wall_s"] / s["wall_s"]
    cpu = float(open(f"{out}/cpu-{w}").read())
    print(f"| {w} | {s['wall_s']:.1f} | {speedup:.2f}x | {cpu:.1f} | {worker:.1f} | {merge:.2f} | {100 * merge / worker:.1f}% |")
print()
for j in rows[2]["jobs"]:
    print(f"- {j['name']}: {j['shards']} shards, wall {j['wall_s']:.1f} s on 2 workers, merge {j['merge_s']:.2f} s")
print(f"- the {len(pngs)} PNGs of the two runs are {'the same bytes' if same else 'DIFFERENT'}")
PY
