#!/usr/bin/env python3
"""Russian roulette's survival scale in `pt` (`rr_scale`), measured on ten scenes (issue 20).

For every scene and every scale it renders the scene with RENDERS seeds (`--seed 1..RENDERS`,
`--set rr_scale=K`, everything else the scene's or pt's defaults) and reports:

- MSE: the mean over pixels of the per-pixel sample variance of the luminance across the renders
  (the variance of one image; no reference needed, as in scripts/peers.py), with its standard error
  over pixels;
- rays per sample (closest-hit plus shadow rays, from the render JSON's counters): the cost of a
  sample, which the machine's load cannot skew;
- CPU seconds per render (median);
- the efficiency against scale 1, 1/(MSE x rays) and 1/(MSE x CPU s), as ratios to scale 1's.

The same seeds are used at every scale, so the paths agree up to their first roulette decision that
differs; the ratios are therefore less noisy than the standard errors suggest, but one scene's MSE
can still move by a few per cent from its fireflies (the lamp and breakfast scenes).

Scenes: the peers script's four (the Cornell box, its glossy and glass variants, the door), the
mirror Cornell box and the environment scene of scenes/, and the five imported scenes of
scenes/imported at a quarter of their resolution (written next to them as .quarter-*.toml while the
script runs, so that their relative paths hold).

    /work/peersenv/bin/python docs/lab/scripts/bench_rr_scale.py [--scales 1,2,4] [--renders 8] [--threads 2]
        [--scenes veach-lamp,torus]

`--variants "rr_scale=2;rr_scale=2,rr_depth=3"` compares groups of pt settings instead of scales
(the first group is the base of the ratios), e.g. the roulette's start depth at the default scale.

Needs numpy and mitsuba (for reading EXR files), e.g. the peers virtualenv of DEVELOPERS.md.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


def peers_module():
    import importlib.util
    spec = importlib.util.spec_from_file_location("peers", os.path.join(ROOT, "scripts", "peers.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def quarter_toml(name):
    """scenes/imported/NAME.toml at a quarter of its resolution, next to it (relative paths hold)."""
    src = os.path.join(ROOT, "scenes", "imported", f"{name}.toml")
    text = open(src).read()
    match = re.search(r"^resolution = \[(\d+), (\d+)\]", text, re.M)
    w, h = int(match.group(1)) // 4, int(match.group(2)) // 4
    text = text[:match.start()] + f"resolution = [{w}, {h}]" + text[match.end():]
    dst = os.path.join(ROOT, "scenes", "imported", f".quarter-{name}.toml")
    with open(dst, "w") as f:
        f.write(text)
    return dst


def scenes(peers, tmp):
    """(name, scene path, spp): spp chosen so that one render takes about a second on 2 threads."""
    cc = peers.load_crosscheck()
    out = []
    for name in ["cornell-box", "cornell-glossy", "cornell-glass", "veach-ajar"]:
        path = os.path.join(tmp, f"{name}.xml")
        with open(path, "w") as f:
            f.write(peers.scene_xml(cc, name, 17))
        out.append((name if name != "veach-ajar" else "veach-ajar (door)", path, 64))
    out.append(("cornell-mirror", os.path.join(ROOT, "scenes", "cornell-mirror.toml"), 32))
    out.append(("environment", os.path.join(ROOT, "scenes", "environment.toml"), 16))
    for name, spp in [("living-room", 4), ("staircase", 16), ("breakfast-room", 8), ("torus", 32),
                      ("veach-lamp", 64)]:
        out.append((f"{name} (1/4 res.)", quarter_toml(name), spp))
    return out


def measure(peers, plexus, scene, spp, settings, renders, threads, tmp):
    """MSE of one image and its standard error (peers.py's `variance_per_image`), mean rays per
    sample, median CPU seconds."""
    import mitsuba as mi
    imgs, rays, cpu = [], [], []
    for seed in range(1, renders + 1):
        out = os.path.join(tmp, f"r{seed}.exr")
        cmd = [plexus, "render", scene, "--integrator", "pt", "--spp", str(spp), "--seed", str(seed),
               "--threads", str(threads), *[a for kv in settings for a in ("--set", kv)], "--out", out]
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            # A mistyped setting (e.g. `rr_dept=2`) is refused by plexus: say why, not just that.
            sys.exit(f"{' '.join(cmd)} failed:\n{done.stderr}")
        stats = json.load(open(os.path.join(tmp, f"r{seed}.json")))
        c = stats["counters"]
        rays.append((c["rays"] + c["shadow_rays"]) / c["samples"])
        cpu.append(stats["cpu_time_s"])
        imgs.append(np.array(mi.Bitmap(out))[..., :3])
    mse, se = peers.variance_per_image(imgs)
    return mse, se, statistics.mean(rays), statistics.median(cpu)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--plexus", default=os.path.join(ROOT, "target", "release", "plexus"))
    parser.add_argument("--scales", default="1,2,4")
    parser.add_argument("--renders", type=int, default=8)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--variants", help="';'-separated groups of ','-separated pt settings "
                        "(KEY=VALUE), compared instead of --scales; the first is the base")
    parser.add_argument("--scenes", help="comma-separated names' prefixes (default: all eleven)")
    args = parser.parse_args()
    if args.variants:
        variants = [group.split(",") for group in args.variants.split(";")]
    else:
        scales = [float(s) for s in args.scales.split(",")]
        if scales[0] != 1.0:
            sys.exit("the first scale must be 1 (the ratios are against it)")
        variants = [[f"rr_scale={s:g}"] for s in scales]
    print(f"load average before: {os.getloadavg()[0]:.2f}", file=sys.stderr)
    print("| scene | spp | settings | MSE | rays / sample | CPU s | efficiency vs the first: 1/(MSE x rays) "
          "| 1/(MSE x CPU s) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    peers = peers_module()
    with tempfile.TemporaryDirectory() as tmp:
        try:
            for name, path, spp in scenes(peers, tmp):
                if args.scenes and not any(name.startswith(p) for p in args.scenes.split(",")):
                    continue
                base = None
                for settings in variants:
                    mse, se, rays, cpu = measure(peers, args.plexus, path, spp, settings, args.renders, args.threads,
                                                 tmp)
                    if base is None:
                        base = (mse, rays, cpu)
                    by_rays = base[0] * base[1] / (mse * rays)
                    by_cpu = base[0] * base[2] / (mse * cpu)
                    print(f"| {name} | {spp} | {' '.join(settings)} | {mse:.4g} ± {se / mse * 100:.1f}% | {rays:.3f} "
                          f"| {cpu:.3f} | **{by_rays:.2f}** | {by_cpu:.2f} |", flush=True)
        finally:
            for f in os.listdir(os.path.join(ROOT, "scenes", "imported")):
                if f.startswith(".quarter-"):
                    os.remove(os.path.join(ROOT, "scenes", "imported", f))
    print(f"load average after: {os.getloadavg()[0]:.2f}", file=sys.stderr)


if __name__ == "__main__":
    main()
