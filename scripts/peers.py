#!/usr/bin/env python3
"""Path-tracing efficiency of plexus against Mitsuba 3 (issue 20), on the same scenes.

Scenes: the Cornell box of ../shared/scenes/cornell-box/cbox.xml, its glossy variant (the short
block a blue rough plastic, alpha 0.08, the tall one a rough gold conductor, alpha 0.2, as in
scenes/cornell-glossy.toml), its glass variant (the short block smooth glass, ior 1.5) and the door
(veach-ajar). Both renderers read the same XML: Mitsuba 3 through scripts/crosscheck.py's
`mitsuba_xml` (snake-case names, path integrator, box filter, absolute paths, the scene's
substitutions), plexus by importing that very file on the fly (`plexus render FILE.xml`). The
door needs crosscheck.py's "veach-ajar" entry; without it the door is skipped with a message.

Error is measured without a reference, so that the renderers' model differences (spectral
reduction, the importer's substitutions) do not count as noise: each renderer renders K images
with different seeds, and its MSE per image is the mean over pixels of the per-pixel sample
variance of the luminance across those K images (both estimators are unbiased for their own
image, and seeds give independent images: Owen scrambles are keyed by the seed). Time is the render
time of one image (plexus: `wall_time_s` of its JSON; Mitsuba: the wall time of `mi.render` once
its kernels are compiled, the first render being a discarded warm-up). Efficiency = 1 / (MSE x time).

- equal samples: both at SPP samples per pixel;
- equal time: Mitsuba at the samples per pixel that take plexus's time (SPP x t_plexus / t_mitsuba).

    scripts/peers.sh [--spp 64] [--renders 4] [--depth 16] [--scenes cornell-box,...]

writes the table to stdout (scripts/peers.sh appends it to docs/benchmarks.md by hand: see there).
"""
import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_crosscheck():
    path = os.environ.get("CROSSCHECK", os.path.join(ROOT, "scripts", "crosscheck.py"))
    spec = importlib.util.spec_from_file_location("crosscheck", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def gulbrandsen_conductor(colour, alpha, bsdf_id):
    """A rough conductor of normal-incidence colour `colour` (crosscheck.gulbrandsen per channel)."""
    cc = load_crosscheck()
    eta, k = zip(*[cc.gulbrandsen(c, c) for c in colour])
    return (f'<bsdf type="roughconductor" id="{bsdf_id}"><float name="alpha" value="{alpha}"/>'
            '<string name="distribution" value="ggx"/>'
            f'<rgb name="eta" value="{eta[0]}, {eta[1]}, {eta[2]}"/><rgb name="k" value="{k[0]}, {k[1]}, {k[2]}"/></bsdf>')


def variants(cc):
    """The four scenes: crosscheck configurations at this script's resolution and depth."""
    box = cc.SCENES["cornell-box"]
    # crosscheck.mitsuba_xml inserts replacements literally (no back-references).
    white = '<bsdf type="diffuse" id="white">'

    def block(mesh, bsdf):
        return (rf'cbox_{mesh}.obj"/>\s*<ref id="box"/>', f'cbox_{mesh}.obj"/><ref id="{bsdf}"/>')

    glossy_bsdfs = ('<bsdf type="roughplastic" id="plastic"><float name="alpha" value="0.08"/>'
                    '<string name="distribution" value="ggx"/><float name="int_ior" value="1.5"/>'
                    '<rgb name="diffuse_reflectance" value="0.1, 0.25, 0.6"/></bsdf>'
                    + gulbrandsen_conductor([0.95, 0.75, 0.35], 0.2, "gold"))
    glass_bsdf = '<bsdf type="dielectric" id="glass"><float name="int_ior" value="1.5"/></bsdf>'
    scenes = {
        "cornell-box": dict(box, name="cornell-box", res=(128, 128)),
        "cornell-glossy": dict(box, name="cornell-box", res=(128, 128), subs=box["subs"] + [
            (white, glossy_bsdfs + white), block("smallbox", "plastic"), block("largebox", "gold")]),
        "cornell-glass": dict(box, name="cornell-box", res=(128, 128), subs=box["subs"] + [
            (white, glass_bsdf + white), block("smallbox", "glass")]),
    }
    if "veach-ajar" in cc.SCENES:
        door = cc.SCENES["veach-ajar"]
        scenes["veach-ajar"] = dict(door, name="veach-ajar", res=(160, 90))
    return scenes


def luminance(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def variance_per_image(imgs):
    """Mean over pixels of the per-pixel luminance variance across the images (ddof 1)."""
    lum = np.array([luminance(i) for i in imgs], dtype=np.float64)
    return float(lum.var(axis=0, ddof=1).mean())


def render_plexus(xml_path, spp, seeds, depth, sampler, threads):
    import mitsuba as mi
    plexus = os.environ.get("PLEXUS", os.path.join(ROOT, "target", "release", "plexus"))
    imgs, times = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            out = os.path.join(tmp, f"{seed}.exr")
            subprocess.run([plexus, "render", xml_path, "--integrator", "pt", "--spp", str(spp), "--seed", str(seed),
                            "--threads", str(threads), "--set", f"max_depth={depth}",
                            "--set", f'sampler="{sampler}"', "-o", out],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            imgs.append(np.array(mi.Bitmap(out))[..., :3])
            times.append(json.load(open(os.path.join(tmp, f"{seed}.json")))["wall_time_s"])
    return imgs, float(np.median(times))


def render_mitsuba(mi, scene, spp, seeds):
    mi.render(scene, spp=spp, seed=999_999)  # compiles the kernels
    imgs, times = [], []
    for seed in seeds:
        t = time.perf_counter()
        img = np.array(mi.render(scene, spp=spp, seed=seed))[..., :3]
        times.append(time.perf_counter() - t)
        imgs.append(img)
    return imgs, float(np.median(times))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="cornell-box,cornell-glossy,cornell-glass,veach-ajar")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--renders", type=int, default=4)
    ap.add_argument("--depth", type=int, default=16, help="plexus max_depth (bounces); Mitsuba gets one more")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    args = ap.parse_args()
    cc = load_crosscheck()
    import mitsuba as mi
    import drjit as dr
    mi.set_variant(args.variant)
    if args.variant.startswith("llvm"):
        dr.set_thread_count(args.threads)
    seeds = [1 + k for k in range(args.renders)]
    scenes = variants(cc)
    print(f"| scene | plexus sampler | spp | plexus s | plexus MSE | Mitsuba 3 ({args.variant}) s | Mitsuba MSE "
          f"| efficiency plexus / Mitsuba, equal samples | Mitsuba spp at plexus's time | Mitsuba MSE there "
          f"| efficiency ratio, equal time |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in args.scenes.split(","):
        if name not in scenes:
            print(f"peers.py: skipping {name}: scripts/crosscheck.py has no '{name}' entry", file=sys.stderr)
            continue
        cfg = dict(scenes[name], depth=args.depth + 1)
        xml = cc.mitsuba_xml(cfg["name"], cfg)
        with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
            f.write(xml)
        try:
            scene = mi.load_file(f.name)
            m_imgs, m_t = render_mitsuba(mi, scene, args.spp, seeds)
            m_var = variance_per_image(m_imgs)
            for sampler in ["independent", "sobol"]:
                p_imgs, p_t = render_plexus(f.name, args.spp, seeds, args.depth, sampler, args.threads)
                p_var = variance_per_image(p_imgs)
                eq_spp = max(1, round(args.spp * p_t / m_t))
                e_imgs, e_t = render_mitsuba(mi, scene, eq_spp, seeds)
                e_var = variance_per_image(e_imgs)
                print(f"| {name} | {sampler} | {args.spp} | {p_t:.3g} | {p_var:.3g} | {m_t:.3g} | {m_var:.3g} "
                      f"| {(m_var * m_t) / (p_var * p_t):.2f} | {eq_spp} ({e_t:.3g} s) | {e_var:.3g} "
                      f"| {(e_var * e_t) / (p_var * p_t):.2f} |", flush=True)
        finally:
            os.unlink(f.name)


if __name__ == "__main__":
    main()
