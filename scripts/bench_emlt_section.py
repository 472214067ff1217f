#!/usr/bin/env python3
"""The `emlt` vs `pmlt` section of docs/benchmarks.md from scripts/bench-emlt.sh's runs.

Usage: scripts/bench_emlt_section.py BENCHMARKS_MD OUT_DIR [OUT_DIR ...]

Reads each OUT_DIR/runs.jsonl and OUT_DIR/machine.txt, writes OUT_DIR/runs.csv and replaces the text
between `<!-- emlt-bench:begin -->` and `<!-- emlt-bench:end -->` in BENCHMARKS_MD (appending the
section with its heading if the markers are missing). Means are over seeds with their standard
error (sample standard deviation / sqrt(n)); the ratio emlt/pmlt is of the means, with its
standard error propagated to first order from the two independent means.
"""
import csv
import json
import math
import os
import statistics
import sys

BEGIN, END = "<!-- emlt-bench:begin -->", "<!-- emlt-bench:end -->"
HEADING = "## Ensemble MLT vs path-space MLT at equal mutations (issue 16)"


def mean_se(values):
    m = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else float("nan")
    return m, se


def fmt(m, se):
    return f"{m:.3g} ± {se:.2g}"


def main():
    page, outs = sys.argv[1], sys.argv[2:]
    all_runs, machines = [], []
    for out in outs:
        runs = [json.loads(line) for line in open(os.path.join(out, "runs.jsonl")) if line.strip()]
        machines.append(f"{out}: " + open(os.path.join(out, "machine.txt")).read().strip())
        write_csv(out, runs)
        all_runs += runs
    write_section(page, all_runs, machines)


def write_csv(out, runs):
    fields = ["scene", "method", "seed", "mse", "relmse", "mean_ratio", "mutations", "render_wall_s",
              "process_wall_s", "cpu_s", "acceptance", "guided_share", "load1_before"]
    with open(os.path.join(out, "runs.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(fields + ["strategies (name:selected share:acceptance)"])
        for r in runs:
            total = sum(s["selected"] for s in r["strategies"]) or 1
            strat = " ".join(f"{s['name']}:{s['selected'] / total:.3f}:{(s['acceptance'] or 0):.3f}"
                             for s in r["strategies"])
            w.writerow([r[k] for k in fields] + [strat])


def write_section(page, runs, machines):
    scenes = list(dict.fromkeys(r["scene"] for r in runs))
    methods = list(dict.fromkeys(r["method"] for r in runs))
    seeds = sorted({r["seed"] for r in runs})
    mpp = sorted({round(r["mutations_per_pixel"]) for r in runs})
    lines = [BEGIN, ""]
    lines.append(f"`scripts/bench-emlt.sh` (MPP={'/'.join(map(str, mpp))}, seeds "
                 f"{seeds[0]}–{seeds[-1]}): {'; '.join(machines)}. Loads before each render from "
                 f"{min(r['load1_before'] for r in runs):.1f} to {max(r['load1_before'] for r in runs):.1f}. "
                 "MSE and relMSE (ε = 0.01) of `plexus compare` against the committed references, "
                 "at the reference's resolution and max_depth 8; mean ± standard error over seeds; "
                 "both methods at their defaults (pmlt's portal perturbation on where the scene has "
                 "a portal). Time per mutation is the render's wall time (bootstrap included) over "
                 "its mutations; CPU is the process's user + system time.")
    lines.append("")
    lines.append("| scene | method | MSE | relMSE | emlt/pmlt MSE | wall s | CPU s | µs/mutation (wall) | acceptance | guided share |")
    lines.append("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for scene in scenes:
        by = {m: [r for r in runs if r["scene"] == scene and r["method"] == m] for m in methods}
        ratio = ""
        if by.get("emlt") and by.get("pmlt"):
            (a, sa), (b, sb) = mean_se([r["mse"] for r in by["emlt"]]), mean_se([r["mse"] for r in by["pmlt"]])
            q = a / b
            ratio = f"{q:.2f} ± {q * math.hypot(sa / a, sb / b):.2f}"
        present = [m for m in methods if by[m]]
        res = "×".join(map(str, by[present[0]][0]["resolution"]))
        for m in present:
            rs = by[m]
            guided = [r["guided_share"] for r in rs if r["guided_share"] is not None]
            lines.append("| " + " | ".join([
                f"{scene} ({res})", f"`{m}`",
                fmt(*mean_se([r["mse"] for r in rs])),
                fmt(*mean_se([r["relmse"] for r in rs])),
                ratio if m == "emlt" else "",
                f"{statistics.median(r['render_wall_s'] for r in rs):.1f}",
                f"{statistics.median(r['cpu_s'] for r in rs):.1f}",
                f"{statistics.median(1e6 * r['render_wall_s'] / r['mutations'] for r in rs):.1f}",
                f"{statistics.fmean(r['acceptance'] for r in rs):.3f}",
                f"{statistics.fmean(guided):.3f}" if guided else "—",
            ]) + " |")
    lines.append("")
    lines.append("Wall and CPU seconds are medians over seeds. Acceptance per strategy "
                 "(mean over seeds; share of the proposals in brackets):")
    lines.append("")
    lines.append("| scene | method | strategy: acceptance (share of proposals) |")
    lines.append("| --- | --- | --- |")
    for scene in scenes:
        for m in methods:
            rs = [r for r in runs if r["scene"] == scene and r["method"] == m]
            if not rs:
                continue
            names = list(dict.fromkeys(s["name"] for r in rs for s in r["strategies"]))
            cells = []
            for name in names:
                sel = sum(s["selected"] for r in rs for s in r["strategies"] if s["name"] == name)
                tot = sum(s["selected"] for r in rs for s in r["strategies"])
                acc = [s["acceptance"] for r in rs for s in r["strategies"]
                       if s["name"] == name and s["acceptance"] is not None]
                if sel == 0:
                    continue
                cells.append(f"{name} {statistics.fmean(acc):.3f} ({sel / tot:.2f})" if acc
                             else f"{name} — ({sel / tot:.2f})")
            lines.append(f"| {scene} | `{m}` | " + ", ".join(cells) + " |")
    lines += ["", END]
    section = "\n".join(lines)

    text = open(page).read()
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + section + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + HEADING + "\n\n" + section + "\n"
    open(page, "w").write(text)


if __name__ == "__main__":
    main()
