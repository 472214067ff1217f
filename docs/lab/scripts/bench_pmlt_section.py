#!/usr/bin/env python3
"""Writes pmlt's section of docs/lab/benchmarks-history.md from what docs/lab/scripts/bench-pmlt.sh produced.

Usage: docs/lab/scripts/bench_pmlt_section.py [OUT]   (OUT defaults to docs/lab/data/pmlt)

Reads OUT/<scene>-converge.csv (`plexus converge`'s rows, one render each), OUT/<scene>-cpu.csv (each
render's CPU time and the load around it), OUT/<scene>-strategies.json (pmlt's strategy statistics),
OUT/<scene>-machine.txt and OUT/reading.md (the hand-written interpretation), and replaces the text between
the markers `<!-- pmlt-bench:begin -->` and `<!-- pmlt-bench:end -->` of docs/lab/benchmarks-history.md (appending
the markers at the end of the page the first time). Nothing else on the page changes.
"""
import csv
import json
import os
import statistics
import sys
from collections import defaultdict

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
SCENES = ["cornell-box", "cornell-glossy", "cornell-glass", "veach-ajar"]
BEGIN, END = "<!-- pmlt-bench:begin -->", "<!-- pmlt-bench:end -->"


def read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def mean_std(values):
    m = statistics.mean(values)
    s = statistics.stdev(values) if len(values) > 1 else float("nan")
    return m, s


def error_table(data, integrators, metric, title):
    lines = [title, "", "| scene (budget) | " + " | ".join(integrators) + " | pmlt ÷ best other |",
             "|---|" + "---:|" * (len(integrators) + 1)]
    for scene, rows, _ in data:
        by = defaultdict(list)
        for r in rows:
            by[r["integrator"]].append(float(r[metric]))
        means = {i: mean_std(v) for i, v in by.items()}
        best = min(means, key=lambda i: means[i][0])
        cells = []
        for i in integrators:
            if i not in means:
                cells.append("—")
                continue
            m, s = means[i]
            text = "%.3e ± %.1e" % (m, s)
            cells.append("**%s**" % text if i == best else text)
        others = [means[i][0] for i in means if not i.startswith("pmlt")]
        ratio = "%.2f×" % (means["pmlt"][0] / min(others)) if "pmlt" in means and others else "—"
        budget = rows[0]["budget"]
        lines.append("| %s (%s s) | %s | %s |" % (scene, budget, " | ".join(cells), ratio))
    return "\n".join(lines)


def work_table(data, integrators):
    lines = ["Work each render got (mean over seeds): CPU seconds of the render's process (user + sys, all",
             "threads; on an idle machine about threads × budget) and samples or mutations per second of wall time:",
             "", "| scene | " + " | ".join(integrators) + " | load average (1 min) around the renders |",
             "|---|" + "---:|" * len(integrators) + "---|"]
    for scene, rows, cpu in data:
        c = defaultdict(list)
        for r in cpu:
            c[r["integrator"]].append(float(r["cpu_s"]))
        rate = defaultdict(list)
        for r in rows:
            rate[r["integrator"]].append(float(r["samples_or_mutations"]) / float(r["wall_time"]))
        cells = ["%.1f s (min %.1f), %.3g/s" % (statistics.mean(c[i]), min(c[i]), statistics.mean(rate[i]))
                 if i in c else "—" for i in integrators]
        loads = [float(r[k]) for r in cpu for k in ("load1_before", "load1_after")]
        load = "%.1f–%.1f (median %.1f)" % (min(loads), max(loads), statistics.median(loads))
        lines.append("| %s | %s | %s |" % (scene, " | ".join(cells), load))
    starved = []
    for scene, rows, cpu in data:
        median = statistics.median(float(r["cpu_s"]) for r in cpu)
        starved += ["%s %s seed %s (%.1f s of CPU, the scene's median %.1f s)" % (
            scene, r["integrator"], r["seed"], float(r["cpu_s"]), median)
            for r in cpu if float(r["cpu_s"]) < 0.5 * median]
    lines.append("")
    lines.append("Renders that got less than half their scene's median CPU time (a load spike; their errors are in "
                 "the means above): %s." % ("; ".join(starved) if starved else "none"))
    return "\n".join(lines)


def pct(num, den):
    return "%.1f%%" % (100.0 * num / den) if den else "—"


def acceptance_table(out, scenes):
    lines = ["| scene | strategy | share of iterations | failed before a path | f(ȳ) > 0 | accepted "
             "| mean acceptance probability |", "|---|---|---:|---:|---:|---:|---:|"]
    for scene in scenes:
        path = os.path.join(out, scene + "-strategies.json")
        if not os.path.exists(path):
            continue
        with open(path) as f:
            runs = json.load(f)
        total = defaultdict(lambda: defaultdict(float))
        order = []
        for run in runs:
            for s in run["strategies"]:
                name = s["name"]
                if name not in order:
                    order.append(name)
                t = total[name]
                t["selected"] += s["selected"]
                t["failures"] += s["generation_failures"]
                t["nonzero"] += s["nonzero_proposals"]
                t["accepted"] += s["accepted"]
                t["probability"] += s["acceptance_probability_sum"]
        iterations = sum(total[n]["selected"] for n in order)
        for name in order:
            t = total[name]
            lines.append("| %s | %s | %s | %s | %s | %s | %s |" % (
                scene, name, pct(t["selected"], iterations), pct(t["failures"], t["selected"]),
                pct(t["nonzero"], t["selected"]), pct(t["accepted"], t["selected"]),
                pct(t["probability"], t["selected"])))
        lines.append("| %s | (%d renders, %d iterations) | | | | | |" % (scene, len(runs), iterations))
    return "\n".join(lines)


def section(out):
    data = []
    integrators = []
    for scene in SCENES:
        path = os.path.join(out, scene + "-converge.csv")
        if not os.path.exists(path):
            continue
        rows = read_csv(path)
        cpu = read_csv(os.path.join(out, scene + "-cpu.csv"))
        for r in rows:
            if r["integrator"] not in integrators:
                integrators.append(r["integrator"])
        data.append((scene, rows, cpu))
    seeds = sorted({int(r["seed"]) for _, rows, _ in data for r in rows})
    machine = []
    for scene, _, _ in data:
        with open(os.path.join(out, scene + "-machine.txt")) as f:
            machine.append("- %s: %s" % (scene, f.read().strip()))
    with open(os.path.join(out, "reading.md")) as f:
        reading = f.read().strip()
    acceptance_scenes = [v for s in SCENES for v in (s, s + "-noportal")
                         if os.path.exists(os.path.join(out, v + "-strategies.json"))]
    rel = os.path.relpath(out, os.path.join(ROOT, "docs"))
    parts = [
        "## Path-space MLT (`pmlt`, issues 13 and 14)\n",
        "`pmlt` (bidirectional mutation with Veach's lens, caustic and multi-chain perturbations, and the portal\n"
        "perturbation where the scene has portals, all at their defaults; `pmlt-noportal`: the same with\n"
        "`portal = 0`, on the door scene, whose doorway has a portal) against %s at equal wall time on the four benchmark scenes, %d seeds (%s), every\n"
        "integrator at `max_depth = 8` as the references, 2 threads, at the references' resolution. Regenerate\n"
        "(this section only; the rest of the page is not touched):\n"
        % (", ".join("`%s`" % i for i in integrators if not i.startswith("pmlt")), len(seeds), ", ".join(map(str, seeds))),
        "```\ndocs/lab/scripts/bench-pmlt.sh        # TIME=12 DOOR_TIME=20 SEEDS=3 THREADS=2 by default; ~20 min of wall time\n```\n",
        "Each render is one `plexus converge` run of one integrator and one seed; the integrators are\n"
        "interleaved within each seed, in an order rotated from seed to seed, so that a change of the machine's\n"
        "load hits them alike. Per-render rows: `docs/%s/<scene>-converge.csv` (converge's CSV; `--replot` redraws\n"
        "its tables) and `<scene>-cpu.csv` (CPU time and load around each render).\n" % rel,
        "**Machine** (recorded when each scene's renders started):\n\n%s\n" % "\n".join(machine),
        "**On a shared machine** equal wall time is not equal work: the CPU column below says how much each\n"
        "render actually got. To measure on a quiet machine, run the same command with nothing else running\n"
        "(`uptime` below 1): each render then gets about 2 × its budget of CPU time, and the ratios are the ones\n"
        "to quote. With more seeds (`SEEDS=10`) the MLT methods' seed-to-seed spread, which dominates here,\n"
        "shrinks as 1/√seeds.\n",
        error_table(data, integrators, "relmse",
                    "relMSE (ε = 1e-2) against the reference, mean ± sample std over the seeds; bold: lowest:") + "\n",
        error_table(data, integrators, "mse", "MSE, mean ± sample std over the seeds:") + "\n",
        work_table(data, integrators) + "\n",
        "**Per-strategy acceptance** of `pmlt` (%s; `-noportal`: `portal = 0`; the render JSON's `integrator_stats.strategies`, summed over\n"
        "one render per seed at the same budget and resolution). Share: iterations that chose the strategy;\n"
        "the other columns are fractions of those iterations:\n" % ", ".join(acceptance_scenes),
        acceptance_table(out, acceptance_scenes) + "\n",
        reading + "\n",
    ]
    return "\n".join(parts)


def main():
    out = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "lab", "data", "pmlt"))
    text = section(out)
    page_path = os.path.join(ROOT, "docs", "lab", "benchmarks-history.md")
    with open(page_path) as f:
        page = f.read()
    block = BEGIN + "\n" + text + END
    if BEGIN in page and END in page:
        start = page.index(BEGIN)
        end = page.index(END) + len(END)
        page = page[:start] + block + page[end:]
    else:
        page = page.rstrip("\n") + "\n\n" + block + "\n"
    with open(page_path, "w") as f:
        f.write(page)


if __name__ == "__main__":
    main()
