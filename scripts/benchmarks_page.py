#!/usr/bin/env python3
"""Writes docs/benchmarks.md from what scripts/benchmarks.sh produced.

Usage: scripts/benchmarks_page.py   (from anywhere; paths are relative to the repository)

Reads docs/bench/<scene>-converge.csv and .md (written by `plexus converge`) for the four benchmark
scenes and docs/bench/reading.md (the hand-written interpretation, which must be revisited when the
numbers change), and writes docs/benchmarks.md: how to regenerate everything, what is measured, the
machine, a summary of equal-time rankings computed from the CSVs, and per scene the plot and the
tables exactly as `plexus converge` wrote them.
"""
import csv
import json
import os
import re
import statistics
from collections import defaultdict

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
SCENES = [
    ("cornell-box", "the Cornell box: diffuse walls and boxes, one area light in the ceiling", "128×128"),
    ("cornell-glossy", "the Cornell box with glossy (rough conductor and plastic) boxes", "128×128"),
    ("cornell-glass", "the Cornell box with a glass sphere: caustics on the floor", "128×128"),
    ("veach-ajar", "the door scene: the light reaches the visible room only through the gap of an ajar door "
     "(the MMLT paper's Fig. 1)", "160×90"),
]


def read_rows(scene):
    path = os.path.join(ROOT, "docs", "bench", scene + "-converge.csv")
    with open(path) as f:
        return list(csv.DictReader(f))


def tables_from_md(scene):
    """The part of `plexus converge`'s Markdown after its command block: the three tables."""
    path = os.path.join(ROOT, "docs", "bench", scene + "-converge.md")
    with open(path) as f:
        text = f.read()
    fence = text.find("```")
    end = text.find("```", fence + 3)
    head, rest = text[:fence], text[end + 3:]
    seeds_line = [line for line in head.splitlines() if line.startswith("Reference:")]
    command = text[fence + 3:end].strip()
    return (seeds_line[0] if seeds_line else ""), command, rest.strip()


def ranking(rows, metric):
    """Per budget: integrators sorted by mean `metric` over seeds."""
    by = defaultdict(list)
    for r in rows:
        by[(r["budget"], r["integrator"])].append(float(r[metric]))
    budgets = sorted({b for b, _ in by}, key=float)
    out = {}
    for b in budgets:
        means = sorted((statistics.mean(v), name) for (bb, name), v in by.items() if bb == b)
        out[b] = means
    return out


def fmt_budget(b):
    return ("%g" % float(b)) + " s"


def summary(scenes_rows):
    lines = [
        "Lowest mean error at each budget (ratios are the runner-up's and the worst integrator's mean error",
        "over the winner's; from the CSVs, so they round nothing):",
        "",
        "| scene | budget | lowest relMSE | runner-up (×) | worst (×) | lowest MSE | runner-up (×) |",
        "|---|---|---|---|---|---|---|",
    ]
    for scene, rows in scenes_rows:
        rel = ranking(rows, "relmse")
        mse = ranking(rows, "mse")
        for b in rel:
            r, m = rel[b], mse[b]
            lines.append(
                "| %s | %s | %s | %s (%.2f×) | %s (%.1f×) | %s | %s (%.2f×) |"
                % (scene, fmt_budget(b), r[0][1], r[1][1], r[1][0] / r[0][0], r[-1][1], r[-1][0] / r[0][0],
                   m[0][1], m[1][1], m[1][0] / m[0][0]))
    return "\n".join(lines)


def machine():
    """What scripts/benchmarks.sh recorded of the machine and the build when it ran."""
    try:
        with open(os.path.join(ROOT, "docs", "bench", "machine.txt")) as f:
            return f.read().strip()
    except OSError:
        return "not recorded (docs/bench/machine.txt is missing)"


def reference_noise(scene, rows):
    """(reference spp, PT spp at the longest budget, estimated variance of the reference, PT's mean
    MSE at the longest budget). The reference is PT with the same settings, so its per-pixel
    variance is c / spp_ref where c / spp is PT's expected MSE at spp samples per pixel. Fitting
    the measured MSE_i = c (1 / spp_i + 1 / spp_ref) (the render's variance plus the reference's)
    over PT's runs gives c."""
    with open(os.path.join(ROOT, "references", scene + ".json")) as f:
        ref = json.load(f)
    spp_ref = float(ref["integrator_stats"]["spp"])
    width, height = ref["resolution"]
    pixels = float(width * height)
    pt = [r for r in rows if r["integrator"] == "pt"]
    x = [pixels / float(r["samples_or_mutations"]) + 1.0 / spp_ref for r in pt]
    y = [float(r["mse"]) for r in pt]
    c = sum(a * b for a, b in zip(x, y)) / sum(a * a for a in x)
    longest = max(float(r["budget"]) for r in pt)
    last = [r for r in pt if float(r["budget"]) == longest]
    spp_pt = statistics.mean(float(r["samples_or_mutations"]) for r in last) / pixels
    mse_pt = statistics.mean(float(r["mse"]) for r in last)
    return spp_ref, spp_pt, c / spp_ref, mse_pt


def noise_table(scenes_rows):
    lines = [
        "| scene | reference spp | PT spp at the longest budget | estimated reference variance (MSE floor) | "
        "share of PT's MSE there |",
        "|---|---:|---:|---:|---:|",
    ]
    for scene, rows in scenes_rows:
        spp_ref, spp_pt, floor, mse_pt = reference_noise(scene, rows)
        lines.append("| %s | %d | %.0f | %.2e | %.0f%% |" % (scene, spp_ref, spp_pt, floor, 100.0 * floor / mse_pt))
    return "\n".join(lines)


def kept_sections(path):
    """Sections other scripts own, kept across a regeneration: the text from `<!-- NAME:begin -->` to
    `<!-- NAME:end -->` in the current page (scripts/bench-pmlt.sh writes its section this way)."""
    try:
        with open(path) as f:
            page = f.read()
    except OSError:
        return []
    return [m.group(0) for m in re.finditer(r"<!-- ([\w-]+):begin -->.*?<!-- \1:end -->", page, re.S)]


def main():
    scenes_rows = [(s, read_rows(s)) for s, _, _ in SCENES]
    seeds = sorted({int(r["seed"]) for _, rows in scenes_rows for r in rows})
    budgets = sorted({r["budget"] for _, rows in scenes_rows for r in rows}, key=float)
    integrators = []
    for _, rows in scenes_rows:
        for r in rows:
            if r["integrator"] not in integrators:
                integrators.append(r["integrator"])
    with open(os.path.join(ROOT, "docs", "bench", "reading.md")) as f:
        reading = f.read().strip()

    out = []
    out.append("# Benchmarks: error against render time\n")
    out.append(
        "How much accuracy each integrator buys per second, on four shipped scenes, measured with `plexus converge`\n"
        "against long path-traced references. Integrators: %s. Budgets: %s. Seeds: %s (%d per cell).\n"
        % (", ".join("`%s`" % i for i in integrators), ", ".join(fmt_budget(b) for b in budgets),
           ", ".join(map(str, seeds)), len(seeds)))
    out.append("Everything on this page regenerates with two scripts (this page itself with the third):\n")
    out.append("```\n"
               "scripts/make-references.sh             # references/*.exr: PT, max_depth 8, 4096 spp (veach-ajar 8192); ~20 min\n"
               "scripts/benchmarks.sh all 3,6,12 3     # docs/bench/*-converge.{csv,md}, docs/img/*-converge.png; ~30 min\n"
               "scripts/benchmarks_page.py             # this page, from those files and docs/bench/reading.md\n"
               "```\n")
    out.append("For each scene S, `scripts/benchmarks.sh` runs:\n")
    out.append("```\n" + tables_from_md(SCENES[0][0])[1].replace(SCENES[0][0], "S") + "\n```\n")
    out.append("Tables and plots redraw from a CSV without rendering: "
               "`plexus converge scenes/S.toml --replot docs/bench/S-converge.csv --out-dir DIR`.\n")
    out.append("## What is measured\n")
    out.append(
        "- **MSE** = mean over pixels and channels of (a − b)²; **relMSE** = mean of (a − b)²/(b² + ε), ε = 1e-2\n"
        "  (definitions in `src/metrics/compare.rs`); b is the reference. relMSE weighs dark regions as much as\n"
        "  bright ones, MSE is dominated by the bright ones: read both.\n"
        "- Each cell: mean ± sample standard deviation (n − 1) over the seeds, with the **mean wall time actually\n"
        "  spent** in parentheses. Bold: lowest mean in the column.\n"
        "- Every integrator runs with `max_depth = 8` (the MLT papers' L), as the references, so an error is noise\n"
        "  and not a difference in which paths are counted; other settings are the defaults of the README's table.\n"
        "- A time budget covers the whole render, MLT's bootstrap included; passes are short (one sample per pixel,\n"
        "  or about one mutation per pixel), so every render ends within about one pass of its budget (the wall\n"
        "  times in parentheses).\n"
        "- CSV columns: integrator, seed, budget, wall_time, samples_or_mutations, rays, mse, relmse,\n"
        "  nonfinite_dropped (the number of non-finite contributions dropped; zero in every run here: %s).\n"
        % ("checked" if all(r["nonfinite_dropped"] == "0" for _, rows in scenes_rows for r in rows)
           else "NOT zero in some runs, see the CSVs"))
    out.append("## Machine and caveats\n")
    out.append(
        "- **Machine and build** (recorded by the script when it ran): %s. 2 worker threads, release build.\n"
        "  Other work may share the machine, so absolute rates are indicative; the rankings and ratios within\n"
        "  one scene, measured in one run, are what to read.\n"
        "- **Few seeds**: with %d seeds the standard deviations are rough; MLT errors vary more across seeds than\n"
        "  independent-sample integrators' (a chain that finds a bright path late leaves a blotch). Differences\n"
        "  within about one standard deviation are not significant.\n"
        "- **Reference noise** adds to every MSE: E[MSE] = the render's own MSE + the reference's variance, a\n"
        "  floor no integrator can go below. Estimated from PT's runs (the reference is PT with the same\n"
        "  settings, so its variance is PT's per-sample variance over its sample count):\n\n"
        "%s\n\n"
        "  Subtract the floor before comparing an integrator whose MSE is close to it (the light tracer's on the\n"
        "  Cornell scenes): its own error is smaller than the table says, so ratios against it are understated.\n"
        % (machine(), len(seeds), noise_table(scenes_rows)))
    out.append("## Summary\n")
    out.append(summary(scenes_rows) + "\n")
    for scene, description, res in SCENES:
        seeds_line, _, tables = tables_from_md(scene)
        out.append("## %s\n" % scene)
        out.append("`scenes/%s.toml`: %s; %s against `references/%s.exr`.\n" % (scene, description, res, scene))
        out.append("![%s: relMSE and MSE against wall time](img/%s-converge.png)\n" % (scene, scene))
        out.append(tables + "\n")
    out.append("## Reading the results\n")
    out.append(reading + "\n")
    large = os.path.join(ROOT, "docs", "bench", "large-scene.md")
    if os.path.exists(large):
        with open(large) as f:
            out.append(f.read().strip() + "\n")
    page = os.path.join(ROOT, "docs", "benchmarks.md")
    out.extend(block + "\n" for block in kept_sections(page))
    with open(page, "w") as f:
        f.write("\n".join(out))


if __name__ == "__main__":
    main()
