#!/usr/bin/env python3
"""The portal paper's Fig. 4c/d from docs/lab/scripts/bench-portals.sh's traces: for each configuration,
chain 0's image-plane positions (left, the film normalised to [0, 1]², y down) and the trace plot
of y over the first 200 points (right). Plain SVG, no dependencies.

Usage: docs/lab/scripts/portal_trace_svg.py OUT.svg LABEL=TRACE.csv [LABEL=TRACE.csv ...]"""
import csv
import sys


def main():
    out, entries = sys.argv[1], [a.split("=", 1) for a in sys.argv[2:]]
    size, gap, width = 220, 30, 440
    rows = []
    for row, (label, path) in enumerate(entries):
        with open(path) as f:
            points = [(float(r["x"]), float(r["y"])) for r in csv.DictReader(f)]
        top = 20 + row * (size + gap + 20)
        rows.append(f'<text x="0" y="{top - 6}" font-size="12">{label}: {len(points)} points</text>')
        rows.append(f'<rect x="0" y="{top}" width="{size}" height="{size}" fill="none" stroke="#888"/>')
        line = " ".join(f"{x * size:.1f},{top + y * size:.1f}" for x, y in points)
        rows.append(f'<polyline points="{line}" fill="none" stroke="#1f77b4" stroke-width="0.5"/>')
        rows += [f'<circle cx="{x * size:.1f}" cy="{top + y * size:.1f}" r="1.2" fill="#1f77b4"/>' for x, y in points]
        left = size + gap
        rows.append(f'<rect x="{left}" y="{top}" width="{width - size - gap + 200}" height="{size}" fill="none" stroke="#888"/>')
        span = width - size - gap + 200
        trace = points[:200]
        line = " ".join(f"{left + i * span / max(len(trace) - 1, 1):.1f},{top + y * size:.1f}" for i, (_, y) in enumerate(trace))
        rows.append(f'<polyline points="{line}" fill="none" stroke="#d62728" stroke-width="1"/>')
        rows.append(f'<text x="{left}" y="{top + size + 14}" font-size="11">raster y of the first 200 points</text>')
    height = 20 + len(entries) * (size + gap + 20)
    with open(out, "w") as f:
        f.write(f'<svg xmlns="http://www.w3.org/2000/svg" width="{width + 230}" height="{height}" font-family="sans-serif">\n')
        f.write("\n".join(rows))
        f.write("\n</svg>\n")


if __name__ == "__main__":
    main()
