#!/usr/bin/env python3
"""Path-tracing efficiency of plexus against Mitsuba 3 (issue 20), on the same scenes.

Scenes: the Cornell box of scenes/mitsuba/cornell-box/cbox.xml, its glossy variant (the short
block a blue rough plastic, alpha 0.08, the tall one a rough gold conductor, alpha 0.2, as in
scenes/cornell-glossy.toml), its glass variant (the short block smooth glass, ior 1.5) and the door
(veach-ajar). Both renderers read the same XML: Mitsuba 3 through scripts/crosscheck.py's
`mitsuba_xml` (snake-case names, path integrator, box filter, absolute paths, the scene's
substitutions), plexus by importing that very file on the fly (`plexus render FILE.xml`); the
door is crosscheck.py's "veach-ajar" configuration at 160x90.

Error is measured without a reference, so that the renderers' model differences (spectral
reduction, the importer's substitutions) do not count as noise: each renderer renders K images
with different seeds, and its MSE per image is the mean over pixels of the per-pixel sample
variance of the luminance across those K images (both estimators are unbiased for their own
image, and seeds give independent images: Owen scrambles are keyed by the seed), with its standard
error over pixels. Time is the median render time of one image (plexus: `wall_time_s` of its JSON;
Mitsuba: the wall time of `mi.render` once its kernels are compiled, the first render being a
discarded warm-up). Efficiency = 1 / (MSE x time). The renders of one scene are interleaved by seed
(Mitsuba, plexus independent, plexus Sobol), so that the shared machine's changing load falls on
all of them alike; the load average is printed with the table.

- equal samples: both at SPP samples per pixel;
- equal time: Mitsuba at the samples per pixel that take plexus's time (SPP x t_plexus / t_mitsuba).

    scripts/peers.sh [--spp 16] [--renders 8] [--depth 16] [--scenes cornell-box,...] [--write docs/lab/benchmarks-history.md]

prints the table, and with --write puts it into docs/lab/benchmarks-history.md between its markers.
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
    scenes["veach-ajar"] = dict(cc.SCENES["veach-ajar"], name="veach-ajar", res=(160, 90))
    return scenes


def scene_xml(cc, name, depth, res=None):
    """The Mitsuba 3 XML text both renderers read for scene `name` (a key of `variants`): Mitsuba's
    `path` integrator at `depth` path edges (plexus's max_depth + 1), this script's resolution or
    `res` (width, height). Shared with scripts/peers_path_lengths.py."""
    scenes = variants(cc)
    if name not in scenes:
        sys.exit(f"peers.py: unknown scene {name}; known: {', '.join(scenes)}")
    cfg = dict(scenes[name], depth=depth)
    if res is not None:
        cfg["res"] = res
    return cc.mitsuba_xml(cfg["name"], cfg)


def luminance(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def variance_per_image(imgs):
    """Mean over pixels of the per-pixel luminance variance across the images (ddof 1), and its
    standard error: pixels are independent estimates, so the SE is the spread of the per-pixel
    variances over sqrt(pixels). Fireflies make the per-pixel variances heavy-tailed, so this SE
    is itself rough: it says which differences are plainly noise, not a sharp bound."""
    lum = np.array([luminance(i) for i in imgs], dtype=np.float64)
    per_pixel = lum.var(axis=0, ddof=1).ravel()
    return float(per_pixel.mean()), float(per_pixel.std(ddof=1) / np.sqrt(per_pixel.size))


def render_plexus(xml_path, spp, seed, depth, sampler, threads, tmp, settings=()):
    """One plexus render: the image and its render's (wall, CPU) seconds (its JSON). `settings` are
    further `--set KEY=VALUE` overrides of pt's settings."""
    import mitsuba as mi
    plexus = os.environ.get("PLEXUS", os.path.join(ROOT, "target", "release", "plexus"))
    out = os.path.join(tmp, f"{sampler}-{seed}.exr")
    subprocess.run([plexus, "render", xml_path, "--integrator", "pt", "--spp", str(spp), "--seed", str(seed),
                    "--threads", str(threads), "--set", f"max_depth={depth}",
                    "--set", f'sampler="{sampler}"', *[a for kv in settings for a in ("--set", kv)], "-o", out],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    img = np.array(mi.Bitmap(out))[..., :3]
    stats = json.load(open(os.path.join(tmp, f"{sampler}-{seed}.json")))
    return img, (stats["wall_time_s"], stats["cpu_time_s"])


def render_mitsuba(mi, scene, spp, seed):
    """One Mitsuba render (kernels compiled beforehand): the image and its (wall, CPU) seconds,
    the CPU time being the whole Python process's (Dr.Jit's worker threads included)."""
    t, c = time.perf_counter(), time.process_time()
    img = np.array(mi.render(scene, spp=spp, seed=seed))[..., :3]
    return img, (time.perf_counter() - t, time.process_time() - c)


def warm_up(mi, scene, spp):
    """Two discarded renders at `spp`: the first compiles the kernels, and the first render after
    that still took about twice the time of later ones (measured on the door: 1.65 s, then 0.89 s
    at 16 spp; 5.96 s, then 3.15 s at 64)."""
    for seed in (999_999, 999_998):
        np.array(mi.render(scene, spp=spp, seed=seed))


def load_average():
    return os.getloadavg()[0]


SAMPLERS = ["independent", "sobol"]


def measure_scene(mi, scene, xml, args, seeds):
    """Renders interleaved by seed (Mitsuba, then plexus with each sampler), so that a change of
    the machine's load falls on all of them alike; then Mitsuba at the samples per pixel that take
    each plexus sampler's median time, interleaved the same way. Returns one row per sampler."""
    warm_up(mi, scene, args.spp)
    m_imgs, m_times = [], []
    p_imgs = {s: [] for s in SAMPLERS}
    p_times = {s: [] for s in SAMPLERS}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            img, t = render_mitsuba(mi, scene, args.spp, seed)
            m_imgs.append(img)
            m_times.append(t)
            for sampler in SAMPLERS:
                img, t = render_plexus(xml, args.spp, seed, args.depth, sampler, args.threads, tmp, args.set)
                p_imgs[sampler].append(img)
                p_times[sampler].append(t)
    m_t = median_times(m_times)
    eq_spp = {s: max(1, round(args.spp * median_times(p_times[s])[0] / m_t[0])) for s in SAMPLERS}
    e_imgs = {s: [] for s in SAMPLERS}
    e_times = {s: [] for s in SAMPLERS}
    for spp in sorted(set(eq_spp.values())):
        warm_up(mi, scene, spp)
    for seed in seeds:
        for sampler in SAMPLERS:
            img, t = render_mitsuba(mi, scene, eq_spp[sampler], seed)
            e_imgs[sampler].append(img)
            e_times[sampler].append(t)
    m_var = variance_per_image(m_imgs)
    rows = []
    for sampler in SAMPLERS:
        p_t = median_times(p_times[sampler])
        p_var = variance_per_image(p_imgs[sampler])
        e_t = median_times(e_times[sampler])
        e_var = variance_per_image(e_imgs[sampler])
        rows.append(dict(sampler=sampler, p_t=p_t, p_var=p_var, m_t=m_t, m_var=m_var, eq_spp=eq_spp[sampler],
                         e_t=e_t, e_var=e_var))
    return rows


def median_times(times):
    """Median wall and median CPU seconds of a list of (wall, CPU) pairs."""
    return float(np.median([t[0] for t in times])), float(np.median([t[1] for t in times]))


def ratio_with_error(num_var, den_var, num_t, den_t):
    """Efficiency ratio (num_var·num_t)/(den_var·den_t) with the relative error of the variances."""
    r = (num_var[0] * num_t) / (den_var[0] * den_t)
    rel = np.hypot(num_var[1] / num_var[0], den_var[1] / den_var[0])
    return r, rel


def table(rows_by_scene, args):
    """Efficiency ratios per wall-clock second and, in brackets, per CPU second."""
    out = [f"| scene | plexus sampler | spp | plexus s (CPU s) | plexus MSE ± SE | Mitsuba 3 ({args.variant}) s (CPU s) "
           f"| Mitsuba MSE ± SE | efficiency plexus / Mitsuba, equal samples: wall (CPU) | Mitsuba spp at plexus's "
           f"wall time, s | Mitsuba MSE there | efficiency ratio, equal time: wall (CPU) |",
           "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name, rows in rows_by_scene:
        for r in rows:
            eq, rel = ratio_with_error(r["m_var"], r["p_var"], r["m_t"][0], r["p_t"][0])
            eq_cpu, _ = ratio_with_error(r["m_var"], r["p_var"], r["m_t"][1], r["p_t"][1])
            et, et_rel = ratio_with_error(r["e_var"], r["p_var"], r["e_t"][0], r["p_t"][0])
            et_cpu, _ = ratio_with_error(r["e_var"], r["p_var"], r["e_t"][1], r["p_t"][1])
            out.append(f"| {name} | {r['sampler']} | {args.spp} | {r['p_t'][0]:.3g} ({r['p_t'][1]:.3g}) "
                       f"| {r['p_var'][0]:.3g} ± {r['p_var'][1]:.2g} | {r['m_t'][0]:.3g} ({r['m_t'][1]:.3g}) "
                       f"| {r['m_var'][0]:.3g} ± {r['m_var'][1]:.2g} | **{eq:.2f}** ({eq_cpu:.2f}) ± {rel * 100:.0f}% "
                       f"| {r['eq_spp']}, {r['e_t'][0]:.3g} | {r['e_var'][0]:.3g} ± {r['e_var'][1]:.2g} "
                       f"| **{et:.2f}** ({et_cpu:.2f}) ± {et_rel * 100:.0f}% |")
    return "\n".join(out)


BEGIN, END = "<!-- peers.py table begin -->", "<!-- peers.py table end -->"


def write_table(path, text):
    """Replaces the text between the BEGIN and END markers of `path` (docs/lab/benchmarks-history.md)."""
    doc = open(path).read()
    if BEGIN not in doc or END not in doc:
        sys.exit(f"peers.py: {path} has no '{BEGIN}' ... '{END}' markers to write the table between")
    head, rest = doc.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    open(path, "w").write(f"{head}{BEGIN}\n{text}\n{END}{tail}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="cornell-box,cornell-glossy,cornell-glass,veach-ajar")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel (64: issue 20's budget)")
    ap.add_argument("--renders", type=int, default=8)
    ap.add_argument("--depth", type=int, default=16, help="plexus max_depth (bounces); Mitsuba gets one more")
    ap.add_argument("--first-seed", type=int, default=1, help="seeds are first-seed, first-seed + 1, ...")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a further pt setting for plexus (repeatable), e.g. first_bounce_paths=4; "
                    "the table is then not the defaults' and must not be written over it")
    ap.add_argument("--write", metavar="FILE", help="also write the table into FILE between its markers "
                    "(docs/lab/benchmarks-history.md, section 'plexus against Mitsuba 3')")
    args = ap.parse_args()
    if args.set and args.write:
        sys.exit("peers.py: --write records the defaults' table; leave out --set, or --write")
    cc = load_crosscheck()
    import mitsuba as mi
    import drjit as dr
    mi.set_variant(args.variant)
    if args.variant.startswith("llvm"):
        dr.set_thread_count(args.threads)
    seeds = [args.first_seed + k for k in range(args.renders)]
    scenes = variants(cc)
    unknown = [n for n in args.scenes.split(",") if n not in scenes]
    if unknown:
        sys.exit(f"peers.py: unknown scene(s) {', '.join(unknown)}; known: {', '.join(scenes)}")
    load_before = load_average()
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    rows_by_scene = []
    for name in args.scenes.split(","):
        xml = scene_xml(cc, name, args.depth + 1)
        with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
            f.write(xml)
        try:
            scene = mi.load_file(f.name)
            rows = measure_scene(mi, scene, f.name, args, seeds)
        finally:
            os.unlink(f.name)
        rows_by_scene.append((name, rows))
        print("\n".join(table([(name, rows)], args).split("\n")[2:]), file=sys.stderr, flush=True)
    text = table(rows_by_scene, args)
    text += (f"\n\n{started}, `scripts/peers.sh --spp {args.spp} --renders {args.renders} --depth {args.depth} "
             f"--threads {args.threads} --first-seed {args.first_seed}{''.join(f' --set {kv}' for kv in args.set)}`; load average {load_before:.1f} before, {load_average():.1f} after; "
             f"mitsuba {mi.__version__}; times are medians of {args.renders} renders; '± x%' is the ratio's relative error from the variances' standard errors alone.")
    print(text)
    if args.write:
        write_table(args.write, text)


if __name__ == "__main__":
    main()
