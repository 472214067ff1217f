#!/usr/bin/env python3
"""The `emlt` vs `pmlt` section of docs/lab/benchmarks-history.md from docs/lab/scripts/bench-emlt.sh's runs.

Usage: docs/lab/scripts/bench_emlt_section.py [--section NAME] [--equal-time-to LABEL] BENCHMARKS_MD OUT_DIR [OUT_DIR ...]

Reads each OUT_DIR/runs.jsonl and OUT_DIR/machine.txt, writes OUT_DIR/runs.csv and replaces the text
between `<!-- NAME:begin -->` and `<!-- NAME:end -->` in BENCHMARKS_MD (appending the section with
its heading if the markers are missing). NAME is "emlt-bench" (issue 16's table, the default) or
"emlt17-bench" (issue 17's tables: equal mutations with the acceptance change and the CPU overhead
against pmlt, equal time against the `pmlt@time` renders, and the paper's Table 1 layout). Means are over seeds with their standard
error (sample standard deviation / sqrt(n)); the ratio emlt/pmlt is of the means, with its
standard error propagated to first order from the two independent means.
"""
import csv
import json
import math
import os
import statistics
import sys

SECTIONS = {
    "emlt-bench": "## Ensemble MLT vs path-space MLT at equal mutations (issue 16)",
    "emlt17-bench": "## Ensemble MLT part 2: equal mutations, equal time, ablation (issue 17)",
}


def mean_se(values):
    m = statistics.fmean(values)
    se = statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else float("nan")
    return m, se


def fmt(m, se):
    return f"{m:.3g} ± {se:.2g}"


def main():
    args = sys.argv[1:]
    section, equal_time_to = "emlt-bench", "emlt"
    while args and args[0].startswith("--"):
        flag, value, args = args[0], args[1], args[2:]
        if flag == "--section":
            section = value
        elif flag == "--equal-time-to":
            equal_time_to = value
        else:
            sys.exit(f"bench_emlt_section: unknown option {flag}")
    if section not in SECTIONS:
        sys.exit(f"bench_emlt_section: unknown section {section} (one of {', '.join(SECTIONS)})")
    page, outs = args[0], args[1:]
    all_runs, machines = [], []
    for out in outs:
        runs = [json.loads(line) for line in open(os.path.join(out, "runs.jsonl")) if line.strip()]
        machines.append(f"{out}: " + open(os.path.join(out, "machine.txt")).read().strip())
        write_csv(out, runs)
        all_runs += runs
    if section == "emlt-bench":
        text = issue16_section(all_runs, machines)
    else:
        text = issue17_section(all_runs, machines, equal_time_to)
    replace_section(page, section, text)


def write_csv(out, runs):
    fields = ["scene", "method", "seed", "mse", "relmse", "mean_ratio", "mutations", "render_wall_s",
              "process_wall_s", "cpu_s", "load_cpu_s", "acceptance", "guided_share", "load1_before"]
    with open(os.path.join(out, "runs.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(fields + ["strategies (name:selected share:acceptance)"])
        for r in runs:
            total = sum(s["selected"] for s in r["strategies"]) or 1
            strat = " ".join(f"{s['name']}:{s['selected'] / total:.3f}:{(s['acceptance'] or 0):.3f}"
                             for s in r["strategies"])
            w.writerow([r.get(k, "") for k in fields] + [strat])


def issue16_section(runs, machines):
    scenes = list(dict.fromkeys(r["scene"] for r in runs))
    methods = list(dict.fromkeys(r["method"] for r in runs))
    seeds = sorted({r["seed"] for r in runs})
    mpp = sorted({round(r["mutations_per_pixel"]) for r in runs})
    lines = [""]
    lines.append(f"`docs/lab/scripts/bench-emlt.sh` (MPP={'/'.join(map(str, mpp))}, seeds "
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
    lines.append("")
    return "\n".join(lines)


def render_cpu(r):
    """The render's CPU seconds without the scene's loading (bench-emlt.sh's `load_cpu_s`)."""
    return r["cpu_s"] - r.get("load_cpu_s", 0.0)


def ratio_se(a, sa, b, sb):
    """a/b and its standard error to first order (independent means)."""
    q = a / b
    return q, q * math.hypot(sa / a, sb / b)


def issue17_section(runs, machines, equal_time_to):
    scenes = list(dict.fromkeys(r["scene"] for r in runs))
    methods = [m for m in dict.fromkeys(r["method"] for r in runs) if m != "pmlt@time"]
    seeds = sorted({r["seed"] for r in runs})
    by = lambda scene, m: [r for r in runs if r["scene"] == scene and r["method"] == m]
    mse = lambda rs: mean_se([r["mse"] for r in rs])
    lines = [""]
    lines.append(f"`docs/lab/scripts/bench-emlt.sh part2` (seeds {seeds[0]}–{seeds[-1]}): {'; '.join(machines)}. "
                 f"Loads before each render from {min(r['load1_before'] for r in runs):.1f} to "
                 f"{max(r['load1_before'] for r in runs):.1f}. MSE and relMSE (ε = 0.01) of `plexus compare` "
                 "against the committed references at their resolution and max_depth 8; mean ± standard "
                 "error over seeds; every method at its defaults but the setting its label names. "
                 "\"pmlt/X\" is pmlt's MSE over the method's (above 1: the method has the lower MSE, "
                 "the form of the paper's \"1.38–2.93× lower MSE\"). Render CPU is the process's user + "
                 "system time less the scene's loading, median over seeds; the overhead is the method's "
                 "CPU per mutation over pmlt's, less 1; the acceptance change is the method's overall "
                 "acceptance (all strategies, bidirectional included) over pmlt's, less 1.")
    lines += ["", "**Equal mutations** (64 per pixel, the paper's setting):", ""]
    lines.append("| scene | method | mutations per chain | MSE | pmlt/X MSE | relMSE | acceptance | acceptance change | render CPU s | CPU µs/mutation | overhead |")
    lines.append("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    summary = {m: {"acc": [], "cost": [], "ratio": []} for m in methods}
    for scene in scenes:
        base = by(scene, "pmlt")
        if not base:
            continue
        b, sb = mse(base)
        base_acc = statistics.fmean(r["acceptance"] for r in base)
        base_cost = statistics.median(render_cpu(r) / r["mutations"] for r in base)
        res = "×".join(map(str, base[0]["resolution"]))
        for m in methods:
            rs = by(scene, m)
            if not rs:
                continue
            a, sa = mse(rs)
            chains = rs[0]["settings"].get("chains") or 2 * rs[0]["settings"].get("ensemble_size", 0)
            acc = statistics.fmean(r["acceptance"] for r in rs)
            cost = statistics.median(render_cpu(r) / r["mutations"] for r in rs)
            q, sq = ratio_se(b, sb, a, sa)
            if m != "pmlt":
                summary[m]["acc"].append(acc / base_acc - 1)
                summary[m]["cost"].append(cost / base_cost - 1)
                summary[m]["ratio"].append(q)
            lines.append("| " + " | ".join([
                f"{scene} ({res})", f"`{m}`",
                f"{rs[0]['mutations'] / chains:.3g}" if chains else "—",
                fmt(a, sa), "" if m == "pmlt" else f"{q:.2f} ± {sq:.2f}",
                fmt(*mean_se([r["relmse"] for r in rs])),
                f"{acc:.3f}", "" if m == "pmlt" else f"{100 * (acc / base_acc - 1):+.0f}%",
                f"{statistics.median(render_cpu(r) for r in rs):.1f}",
                f"{1e6 * cost:.1f}", "" if m == "pmlt" else f"{100 * (cost / base_cost - 1):+.0f}%",
            ]) + " |")
    lines += ["", "Averages over the scenes (the paper: +14% acceptance, 18% overhead, 1.38–2.93× lower MSE):", ""]
    lines.append("| method | pmlt/X MSE, per scene | acceptance change, mean | overhead, mean |")
    lines.append("| --- | --- | ---: | ---: |")
    for m in methods:
        s = summary[m]
        if s["ratio"]:
            lines.append(f"| `{m}` | {', '.join(f'{q:.2f}' for q in s['ratio'])} | "
                         f"{100 * statistics.fmean(s['acc']):+.0f}% | {100 * statistics.fmean(s['cost']):+.0f}% |")

    timed = [r for r in runs if r["method"] == "pmlt@time"]
    if timed:
        lines += ["", f"**Equal time**: `pmlt@time` is pmlt at the mutations per pixel whose render CPU "
                  f"matches `{equal_time_to}`'s median at 64 (same seeds).", ""]
        lines.append(f"| scene | pmlt@time mutations per pixel | `{equal_time_to}` MSE | pmlt@time MSE | pmlt@time/{equal_time_to} MSE | render CPU s, {equal_time_to} / pmlt@time |")
        lines.append("| --- | ---: | ---: | ---: | ---: | ---: |")
        for scene in scenes:
            t, e = by(scene, "pmlt@time"), by(scene, equal_time_to)
            if not (t and e):
                continue
            (a, sa), (b, sb) = mse(e), mse(t)
            q, sq = ratio_se(b, sb, a, sa)
            lines.append("| " + " | ".join([
                scene, f"{statistics.median(r['mutations_per_pixel'] for r in t):.0f}",
                fmt(a, sa), fmt(b, sb), f"{q:.2f} ± {sq:.2f}",
                f"{statistics.median(render_cpu(r) for r in e):.1f} / {statistics.median(render_cpu(r) for r in t):.1f}",
            ]) + " |")

    ablation = [("MLT (`pmlt`)", "pmlt"), ("Ani", "emlt:perturbations=anisotropic"),
                ("Lin", "emlt"), ("EMLT (all)", "emlt:perturbations=all")]
    ablation = [(name, m) for name, m in ablation if any(r["method"] == m for r in runs)]
    if len(ablation) > 1:
        lines += ["", "**Ablation** (the paper's Table 1: MSE at equal mutations; pmlt/X in brackets):", ""]
        lines.append("| scene | " + " | ".join(name for name, _ in ablation) + " |")
        lines.append("| --- |" + " ---: |" * len(ablation))
        for scene in scenes:
            base = by(scene, "pmlt")
            cells = []
            for _, m in ablation:
                rs = by(scene, m)
                if not rs:
                    cells.append("—")
                    continue
                a, sa = mse(rs)
                cells.append(f"{a:.3g} ± {sa:.1g}" + (f" ({mse(base)[0] / a:.2f})" if base and m != "pmlt" else ""))
            lines.append(f"| {scene} | " + " | ".join(cells) + " |")

    lines += ["", "Acceptance per strategy (mean over seeds; share of the proposals in brackets):", ""]
    lines.append("| scene | method | strategy: acceptance (share of proposals) |")
    lines.append("| --- | --- | --- |")
    for scene in scenes:
        for m in methods:
            rs = by(scene, m)
            if rs:
                lines.append(f"| {scene} | `{m}` | {strategy_cells(rs)} |")
    lines.append("")
    return "\n".join(lines)


def strategy_cells(rs):
    names = list(dict.fromkeys(s["name"] for r in rs for s in r["strategies"]))
    tot = sum(s["selected"] for r in rs for s in r["strategies"]) or 1
    cells = []
    for name in names:
        sel = sum(s["selected"] for r in rs for s in r["strategies"] if s["name"] == name)
        acc = [s["acceptance"] for r in rs for s in r["strategies"] if s["name"] == name and s["acceptance"] is not None]
        if sel:
            cells.append(f"{name} {statistics.fmean(acc):.3f} ({sel / tot:.2f})" if acc else f"{name} — ({sel / tot:.2f})")
    return ", ".join(cells)


def replace_section(page, name, section):
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    section = begin + "\n" + section + "\n" + end
    text = open(page).read()
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        text = head + section + rest.split(end, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + SECTIONS[name] + "\n\n" + section + "\n"
    open(page, "w").write(text)


if __name__ == "__main__":
    main()
