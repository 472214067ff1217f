#!/usr/bin/env python3
"""Rewrites the generated sections of docs/benchmarks.md from what scripts/benchmarks.sh measured.

Usage: scripts/benchmarks_page.py [SCENE ...]   (paths are relative to the repository)

Reads docs/bench/machine.txt (one line per scene: its latest run's commit, machine and load),
docs/bench/<scene>-converge.csv and .md (`plexus converge`'s rows and tables) and
references/<scene>.json (how each reference was made), and replaces the text between
`<!-- BEGIN generated: NAME -->` and `<!-- END generated: NAME -->` in docs/benchmarks.md for
NAME = provenance, summary, noise, and `scene SCENE` for each SCENE given (default: every scene in
machine.txt). Everything outside the markers is hand-written and left as it is. The summary and
noise tables cover every scene in machine.txt; a scene's rows change only when its CSV does.
"""
import csv
import json
import math
import os
import re
import statistics
import sys
from collections import defaultdict

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
PAGE = os.path.join(ROOT, "docs", "benchmarks.md")
BENCH = os.path.join(ROOT, "docs", "bench")
# The order `plexus converge --integrators all` renders them in; columns follow it.
INTEGRATOR_ORDER = ["pt", "bdpt", "light", "pssmlt", "mmlt", "rjmlt", "pmlt", "emlt"]
# A winner is "resolved" when the runner-up's mean error exceeds the winner's by at least this many
# standard errors of the difference (two-sided ~95% under a normal approximation; with 2-3 seeds per
# cell the standard errors are themselves rough, so this separates clear leads from ties, no more).
RESOLVED_SE = 2.0
# A render whose mean wall time exceeds its budget by more than this factor (an integrator that ends
# only at a whole sweep, or a bootstrap longer than the budget) has its wall time shown beside it.
OVERRUN = 1.1


def read_machine():
    """docs/bench/machine.txt as a list of dicts, one per scene, in file order."""
    path = os.path.join(BENCH, "machine.txt")
    with open(path) as f:
        lines = [line.rstrip("\n") for line in f if line.strip() and not line.startswith("#")]
    header = lines[0].split("\t")
    return [dict(zip(header, line.split("\t"))) for line in lines[1:]]


def read_rows(scene):
    with open(os.path.join(BENCH, scene + "-converge.csv")) as f:
        return list(csv.DictReader(f))


def read_reference(scene):
    with open(os.path.join(ROOT, "references", scene + ".json")) as f:
        return json.load(f)


def converge_tables(scene):
    """(command, tables) from `plexus converge`'s Markdown: the command it ran (its binary shown as
    `plexus`) and the three tables after it."""
    with open(os.path.join(BENCH, scene + "-converge.md")) as f:
        text = f.read()
    fence = text.find("```")
    end = text.find("```", fence + 3)
    command = text[fence + 3:end].strip()
    command = re.sub(r"^\S*plexus\b", "plexus", command)
    return command, text[end + 3:].strip()


def cells(rows):
    """{budget: {integrator: (mean MSE, SE of MSE, mean relMSE, SE of relMSE, n, mean wall time)}} over
    the seeds."""
    by = defaultdict(lambda: defaultdict(list))
    wall = defaultdict(list)
    for r in rows:
        by[float(r["budget"])][r["integrator"]].append((float(r["mse"]), float(r["relmse"])))
        wall[(float(r["budget"]), r["integrator"])].append(float(r["wall_time"]))
    out = {}
    for budget, per in by.items():
        out[budget] = {}
        for name, values in per.items():
            n = len(values)
            mse = [v[0] for v in values]
            rel = [v[1] for v in values]
            se = (lambda xs: statistics.stdev(xs) / math.sqrt(n) if n > 1 else float("nan"))
            out[budget][name] = (statistics.mean(mse), se(mse), statistics.mean(rel), se(rel), n,
                                 statistics.mean(wall[(budget, name)]))
    return out


def ordered(names):
    return sorted(names, key=lambda n: (INTEGRATOR_ORDER.index(n) if n in INTEGRATOR_ORDER else 99, n))


def fmt_budget(b):
    return "%g s" % b


def fmt_value(x):
    """As `plexus converge`'s tables write errors: 1.234e-4."""
    mantissa, exponent = ("%.3e" % x).split("e")
    return "%se%d" % (mantissa, int(exponent))


def fmt_ratio(r):
    return ("%.2f×" if r < 10 else "%.1f×" if r < 100 else "%.0f×") % r


def lead(cell, metric):
    """The winner, runner-up, their ratio and the difference in standard errors, for metric 0 (MSE)
    or 2 (relMSE) of one budget's cells."""
    ranked = sorted(cell, key=lambda n: cell[n][metric])
    best, second = ranked[0], ranked[1]
    m1, s1 = cell[best][metric], cell[best][metric + 1]
    m2, s2 = cell[second][metric], cell[second][metric + 1]
    z = (m2 - m1) / math.sqrt(s1 * s1 + s2 * s2) if s1 * s1 + s2 * s2 > 0 else float("nan")
    return best, second, m2 / m1, z


def summary_table(machine, metric, label):
    """Rows: scenes; columns: integrators; the winner's mean error in bold, the others' means as
    multiples of it; then the runner-up's margin."""
    names = ordered({r["integrator"] for m in machine for r in read_rows(m["scene"])})
    lines = [
        "| scene | budget | " + " | ".join("`%s`" % n for n in names) + " | runner-up's margin |",
        "|---|---:|" + "---:|" * len(names) + "---|",
    ]
    for m in machine:
        scene = m["scene"]
        by = cells(read_rows(scene))
        budget = max(by)
        cell = by[budget]
        best, second, ratio, z = lead(cell, metric)
        row = []
        for n in names:
            if n not in cell:
                row.append("–")
            elif n == best:
                row.append("**%s**" % fmt_value(cell[n][metric]))
            else:
                row.append(fmt_ratio(cell[n][metric] / cell[best][metric]))
            if n in cell and cell[n][5] > OVERRUN * budget:
                row[-1] += " (%.1f s)" % cell[n][5]
        if math.isnan(z):
            margin = "`%s` %s (one seed: not resolved)" % (second, fmt_ratio(ratio))
        else:
            verdict = "resolved" if z >= RESOLVED_SE else "not resolved"
            margin = "`%s` %s, %.1f SE: %s" % (second, fmt_ratio(ratio), z, verdict)
        lines.append("| [%s](#%s) | %s | %s | %s |" % (scene, scene, fmt_budget(budget), " | ".join(row), margin))
    return "%s at each scene's longest budget: the lowest mean over the seeds in bold, every other integrator's mean as a multiple of it.\n\n%s" % (
        label, "\n".join(lines))


def summary(machine):
    plots = " ".join(
        '<a href="#%s"><img src="img/%s-converge.png" width="49%%" alt="%s: error against wall time"></a>' %
        (m["scene"], m["scene"], m["scene"]) for m in machine)
    return "\n\n".join([
        summary_table(machine, 0, "**MSE**"),
        summary_table(machine, 2, "**relMSE**"),
        "\"Runner-up's margin\": the second lowest mean as a multiple of the lowest, and their difference in standard "
        "errors of the difference (from the seeds' sample standard deviations); \"resolved\" at %g SE or more. "
        "Computed from the CSVs, so nothing is rounded before the ratios. A time in parentheses: that "
        "integrator's mean wall time, where it overran the budget by more than %d%%." % (
            RESOLVED_SE, round(100 * (OVERRUN - 1))),
        "Error against wall time per scene (log-log; a line through the means over the seeds, the band ±1 standard "
        "deviation; click a plot for the scene's tables):",
        plots,
    ])


def reference_noise(scene, rows):
    """(reference spp, pt's spp at the longest budget, estimated variance of the reference, pt's mean
    MSE there), or None without pt rows. The reference is pt with the same depth, so its per-pixel
    variance is c / spp_ref, where c / spp is pt's expected MSE at spp samples per pixel; fitting the
    measured MSE_i = c (1 / spp_i + 1 / spp_ref) (the render's variance plus the reference's) over
    pt's runs by least squares through the origin gives c."""
    ref = read_reference(scene)
    spp_ref = float(ref["budget"]["samples_per_pixel"])
    width, height = ref["resolution"]
    pixels = float(width * height)
    pt = [r for r in rows if r["integrator"] == "pt"]
    if not pt:
        return None
    x = [pixels / float(r["samples_or_mutations"]) + 1.0 / spp_ref for r in pt]
    y = [float(r["mse"]) for r in pt]
    c = sum(a * b for a, b in zip(x, y)) / sum(a * a for a in x)
    longest = max(float(r["budget"]) for r in pt)
    last = [r for r in pt if float(r["budget"]) == longest]
    spp_pt = statistics.mean(float(r["samples_or_mutations"]) for r in last) / pixels
    mse_pt = statistics.mean(float(r["mse"]) for r in last)
    return spp_ref, spp_pt, c / spp_ref, mse_pt


def noise(machine):
    lines = [
        "| scene | reference | reference spp | `pt` spp at the longest budget | estimated reference variance "
        "(MSE floor) | share of `pt`'s MSE there | lowest MSE there, floor subtracted |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for m in machine:
        scene = m["scene"]
        rows = read_rows(scene)
        est = reference_noise(scene, rows)
        ref = read_reference(scene)
        made = "`%s`, %d×%d, max_depth %s" % (ref["integrator"], ref["resolution"][0], ref["resolution"][1],
                                               ref["settings"]["max_depth"])
        if est is None:
            lines.append("| %s | %s | %d | – | – | – | – |" % (scene, made, ref["budget"]["samples_per_pixel"]))
            continue
        spp_ref, spp_pt, floor, mse_pt = est
        by = cells(rows)
        cell = by[max(by)]
        best = min(cell, key=lambda n: cell[n][0])
        lines.append("| %s | %s | %d | %.0f | %s | %.0f%% | `%s` %s |" % (
            scene, made, spp_ref, spp_pt, fmt_value(floor), 100.0 * floor / mse_pt, best,
            fmt_value(cell[best][0] - floor)))
    return "\n".join(lines)


def provenance(machine):
    first = max(machine, key=lambda m: m["date"])
    lines = [
        "Machine (when the latest scene ran): %s, %s cores, %s GiB. Per scene, the run that produced its rows:" % (
            first["cpu"], first["cores"], first["mem_gib"]),
        "",
        "| scene | date (UTC) | commit | build inputs modified | threads | budgets | seeds | wall time | CPU share "
        "| load average: start, mean, max |",
        "|---|---|---|---|---:|---|---:|---:|---:|---|",
    ]
    for m in machine:
        threads = float(m["threads"])
        share = float(m["cpu_s"]) / (float(m["wall_s"]) * threads) if float(m["wall_s"]) > 0 else float("nan")
        lines.append("| %s | %s | `%s` | %s | %s | %s | %s | %s s | %.0f%% | %s, %s, %s |" % (
            m["scene"], m["date"].replace("T", " "), m["commit"], m["dirty"], m["threads"],
            ", ".join(fmt_budget(float(t)) for t in m["times"].split(",")), m["seeds"], m["wall_s"], 100.0 * share,
            m["load_start"], m["load_mean"], m["load_max"]))
    dropped = sum(int(r["nonfinite_dropped"]) for m in machine for r in read_rows(m["scene"]))
    lines += [
        "",
        "\"Build inputs modified\": whether `src`, `ffi`, `build.rs`, `Cargo.*`, `scenes` or `references` differed "
        "from the commit (uncommitted or untracked files) when the binary was built. \"CPU share\": the CPU time "
        "`plexus converge` got over the wall time and its worker threads (scene loading included); below 100%% "
        "the machine was shared, and equal-time figures measure less work than an idle machine's. The load average "
        "is the 1-minute one, sampled every 10 s; the machine has %s cores." % first["cores"],
        "",
        "Non-finite contributions dropped over all %d renders: %d." % (
            sum(len(read_rows(m["scene"])) for m in machine), dropped),
    ]
    return "\n".join(lines)


def scene_section(m):
    scene = m["scene"]
    ref = read_reference(scene)
    command, tables = converge_tables(scene)
    head = ("`%s` at %d×%d against `references/%s.exr` (`%s`, %d spp, max_depth %s). Rendered %s at `%s` "
            "with:\n\n```\n%s\n```" % (
                ref["scene"], ref["resolution"][0], ref["resolution"][1], scene, ref["integrator"],
                ref["budget"]["samples_per_pixel"], ref["settings"]["max_depth"], m["date"].replace("T", " "),
                m["commit"], command))
    plot = "![%s: relMSE and MSE against wall time](img/%s-converge.png)" % (scene, scene)
    return "\n\n".join([head, plot, tables])


def replace_section(page, name, body):
    begin, end = "<!-- BEGIN generated: %s -->" % name, "<!-- END generated: %s -->" % name
    block = begin + "\n" + body.strip() + "\n" + end
    if begin in page and end in page:
        start = page.index(begin)
        stop = page.index(end) + len(end)
        return page[:start] + block + page[stop:]
    # A scene without a section yet: after the last scene's section, else at the end.
    last = list(re.finditer(r"<!-- END generated: scene [\w-]+ -->", page))
    at = last[-1].end() if last else len(page.rstrip("\n"))
    name_heading = "\n\n## %s\n\n" % name.split(" ", 1)[1] if name.startswith("scene ") else "\n\n"
    return page[:at] + name_heading + block + page[at:]


def main():
    machine = read_machine()
    known = [m["scene"] for m in machine]
    wanted = sys.argv[1:] or known
    for scene in wanted:
        if scene not in known:
            sys.exit("benchmarks_page.py: %s has no line in docs/bench/machine.txt: run scripts/benchmarks.sh "
                     "--scenes %s first" % (scene, scene))
    with open(PAGE) as f:
        page = f.read()
    page = replace_section(page, "provenance", provenance(machine))
    page = replace_section(page, "summary", summary(machine))
    page = replace_section(page, "noise", noise(machine))
    for m in machine:
        if m["scene"] in wanted:
            page = replace_section(page, "scene " + m["scene"], scene_section(m))
    with open(PAGE, "w") as f:
        f.write(page)


if __name__ == "__main__":
    main()
