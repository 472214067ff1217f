#!/usr/bin/env python3
"""The acceptance table of the RJMLT paper's Fig. 4 from an MMLT and an RJMLT render's JSON stats.

Usage: scripts/fig4_table.py MMLT.json RJMLT.json   (writes Markdown to standard output)

Per path depth d (scattering events): (a) the acceptance of RJMLT's small steps, which keep the
technique; (b) the acceptance of MMLT's small steps whose proposal has another technique (MMLT moves
the technique through the primary coordinate u_t, so a technique change comes with a new path);
(c) the acceptance of RJMLT's technique jumps, which keep the path (1 up to rounding, Sec. 6.2).
"""
import json
import sys


def pct(x):
    return "—" if x is None else "%.1f%%" % (100.0 * x)


def main(mmlt_path, rjmlt_path):
    with open(mmlt_path) as f:
        mmlt = json.load(f)["integrator_stats"]
    with open(rjmlt_path) as f:
        rjmlt = json.load(f)["integrator_stats"]
    for name, st in (("MMLT", mmlt), ("RJMLT", rjmlt)):
        if "per_depth" not in st or "mutations" not in st:
            sys.exit("fig4_table: %s rendered no chains: %s" % (name, "; ".join(st.get("warnings", []))))
    jumps = rjmlt["jumps"]
    print("RJMLT jumps in all: %d proposed, %s accepted; %d chose the current technique; %d inverses failed;"
          " %d regenerated paths were off the original; largest |r − 1| = %.2g." % (
              jumps["proposals"], pct(jumps["acceptance"]), jumps["to_same_technique"],
              sum(jumps["inversion_failures"].values()), jumps["path_mismatches"], jumps["ratio_max_deviation"]))
    print()
    print("| depth | (a) RJMLT small steps | (b) MMLT technique changes (proposals) | (c) RJMLT jumps (proposals) |")
    print("| ---: | ---: | ---: | ---: |")
    for m, r in zip(mmlt["per_depth"], rjmlt["per_depth"]):
        tc, jp = m.get("technique_change") or {}, r.get("jumps") or {}
        print("| %s | %s | %s (%s) | %s (%s) |" % (
            m["depth"], pct(r.get("small_step_acceptance")), pct(tc.get("acceptance")), tc.get("proposals", 0),
            pct(jp.get("acceptance")), jp.get("proposals", 0)))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
