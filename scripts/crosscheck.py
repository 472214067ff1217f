#!/usr/bin/env python3
"""Cross-checks plexus against Mitsuba 3 on the imported Mitsuba scenes (issue 18).

Each scene is rendered by Mitsuba 3's path tracer from its original XML (made readable to
Mitsuba 3: names in snake_case, integrator `path` at the given depth, a small box-filtered film,
paths made absolute, and the substitutions listed per scene where Mitsuba 3 lacks a plugin the
file uses, giving it what the importer gave plexus) and by plexus `pt` from scenes/imported/NAME.toml
at the same depth and resolution. Both render K independent images (seeds); per region of a 4x4
grid (and the whole image) the luminance means are compared with the bound

    |mean_plexus - mean_mitsuba| <= Z * sqrt(se_plexus^2 + se_mitsuba^2) + tol * mean_mitsuba

where se is each renderer's standard error from its K renders and tol the scene's stated model
tolerance (SCENES below, with its reason). Z = 5 (Welch's z over 17 comparisons per scene).

    python3 -m venv venv && venv/bin/pip install mitsuba numpy
    venv/bin/python scripts/crosscheck.py [--scenes cornell-box,veach-lamp] [--spp 64] [--renders 8]
                                          [--write-references]

--write-references stores Mitsuba's mean image and its per-region means and standard errors in
references/mitsuba/NAME.{exr,json}, which tests/images/crosscheck.rs checks plexus against without Mitsuba.
The committed references were made with (the budget is per scene; the defaults would make the
interiors' references four times noisier, which is how a 9.5% regional error once hid under the
bound):

    venv/bin/python scripts/crosscheck.py --scenes cornell-box,veach-lamp --spp 256 --renders 8 --write-references
    venv/bin/python scripts/crosscheck.py --scenes staircase,breakfast-room,living-room,veach-ajar,torus \
        --renders 32 --write-references
The plexus binary is $PLEXUS or target/release/plexus; the scenes' XML, meshes and textures are in
scenes/mitsuba/NAME/ (their sources and licences in scenes/mitsuba/LICENSES.md).
"""
import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE_DATA = os.path.join(ROOT, "scenes", "mitsuba")
GRID = 4
Z = 5.0


def gulbrandsen(r, g):
    """plexus's conductor_from_colour (material/fresnel.rs): eta, k per channel from the
    normal-incidence colour r with edge tint g = r (Gulbrandsen 2014)."""
    r = min(max(r, 0.0), 0.9999)
    sr = math.sqrt(r)
    n = g * (1 - r) / (1 + r) + (1 - g) * (1 + sr) / (1 - sr)
    k2 = (r * (n + 1) ** 2 - (n - 1) ** 2) / (1 - r)
    return n, math.sqrt(max(k2, 0.0))


def ward_as_conductor():
    spec = [0.61600, 0.47520, 0.35200]
    eta, k = zip(*[gulbrandsen(c, c) for c in spec])
    return ('<bsdf type="roughconductor" id="LampMaterial"><float name="alpha" value="0.4"/>'
            '<string name="distribution" value="ggx"/>'
            f'<rgb name="eta" value="{eta[0]}, {eta[1]}, {eta[2]}"/><rgb name="k" value="{k[0]}, {k[1]}, {k[2]}"/></bsdf>')


def folded_conductor():
    """The importer folds specular_reflectance 0.578596 over aluminium's eta, k into the colour
    F0 * tint = (0.53696454, 0.531038, 0.5316769) and renders it with Gulbrandsen's eta, k of that
    colour (its warning); Mitsuba gets the same eta, k in place of the tinted aluminium."""
    colour = [0.53696454, 0.531038, 0.5316769]
    eta, k = zip(*[gulbrandsen(c, c) for c in colour])
    return (f'<rgb name="eta" value="{eta[0]}, {eta[1]}, {eta[2]}"/>'
            f'<rgb name="k" value="{k[0]}, {k[1]}, {k[2]}"/>')


def sun_and_sky(direction, distance, sky, sun):
    """The substitute for Mitsuba's sunsky, given to both renderers (Mitsuba 3's sunsky is a
    different sky model from plexus's Preetham and its sun differs in size and spectrum): a
    constant sky of radiance `sky` and the sun as an emitting sphere of angular radius 1 degree at
    `distance` along `direction`, of radiance `sun` (black, so it reflects nothing)."""
    n = math.sqrt(sum(c * c for c in direction))
    c = [distance * x / n for x in direction]
    r = distance * math.tan(math.radians(1.0))
    return (f'<emitter type="constant"><rgb name="radiance" value="{sky}, {sky}, {sky}"/></emitter>'
            f'<shape type="sphere"><point name="center" x="{c[0]}" y="{c[1]}" z="{c[2]}"/>'
            f'<float name="radius" value="{r}"/>'
            '<bsdf type="diffuse"><rgb name="reflectance" value="0, 0, 0"/></bsdf>'
            f'<emitter type="area"><rgb name="radiance" value="{sun}, {sun}, {sun}"/></emitter></shape>')


# Mitsuba-side edits every scene needs, each giving Mitsuba 3 what plexus's importer made of the
# same XML (its warnings in scenes/imported/NAME.warnings): Beckmann is rendered as GGX of the same
# alpha, a trilinear texture filter as bilinear (Mitsuba 3 knows only nearest and bilinear), and
# roughdiffuse as Lambertian (Mitsuba 3 has no roughdiffuse); Mitsuba 0.6's extEta (1 here) is a
# property Mitsuba 3 refuses as unreferenced (plexus ignores it).
COMMON_SUBS = [
    (r'name="distribution" value="beckmann"', 'name="distribution" value="ggx"'),
    (r'value="trilinear"', 'value="bilinear"'),
    (r'<bsdf type="roughdiffuse"\s*>(.*?)<float name="alpha" value="[^"]*"\s*/>', r'<bsdf type="diffuse">\1'),
    (r'<float name="ext(Eta|_eta)" value="1"\s*/>', ''),
    (r'<rfilter type="tent"\s*/>', '<rfilter type="box"/>'),
]
FOLD = (r'<rgb name="specularReflectance" value="0.578596, 0.578596, 0.578596"/>\s*'
        r'<rgb name="eta" value="[^"]*"/>\s*<rgb name="k" value="[^"]*"/>', folded_conductor())

# name: xml, resolution, Mitsuba max_depth (path edges; plexus gets one less: it counts bounces),
# model tolerance with its reason, substitutions (regex, replacement) applied to the Mitsuba side
# only ("subs": what the importer did, given to Mitsuba) or to both ("both": the XML both render,
# imported into scenes/crosscheck/NAME.toml by --write-scenes, where neither renders the original).
SCENES = {
    "cornell-box": dict(
        xml="cbox.xml", res=(64, 64), depth=10, tol=0.03,
        reason="reflectance and emission spectra are reduced to RGB by the importer's analytic CIE fit and "
               "a 6504 K black body for D65 (the red wall within 2.3% of Mitsuba 3's own reduction, the light "
               "within 0.3%); Mitsuba 3 reduces them itself",
        subs=[]),
    "veach-lamp": dict(
        xml="scene.xml", res=(128, 72), depth=6, tol=0.03,
        reason="Mitsuba 3 has no ward BSDF: both renderers get the importer's substitute, a GGX conductor "
               "(alpha 0.4) of the specular colour with plexus's Gulbrandsen eta/k; 3% covers float "
               "differences of the highlights on the lamp shades",
        subs=[(r'<bsdf type="ward" id="LampMaterial">.*?</bsdf>', ward_as_conductor())]),
    "staircase": dict(
        xml="scene.xml", res=(36, 64), depth=9, tol=0.03,
        reason="8-bit sRGB textures decoded by OpenImageIO (plexus) and by Mitsuba's own loader, bilinear "
               "lookups at texel centres, and OBJ normals and uvs read by two loaders",
        subs=COMMON_SUBS + [FOLD]),
    "breakfast-room": dict(
        xml="scene.xml", res=(64, 36), depth=9, tol=0.03,
        reason="as the staircase (textures read by two loaders); the sunsky is replaced in both by the same "
               "constant sky and sun sphere",
        subs=COMMON_SUBS,
        both=[(r'<emitter type="sunsky">.*?</emitter>',
               sun_and_sky((0.88698, 0.288862, 0.360313), 1000.0, 1.0, 3000.0))]),
    "living-room": dict(
        xml="scene.xml", res=(64, 36), depth=9, tol=0.03,
        reason="as the staircase (textures, OBJ), and the environment map read and importance-sampled by "
               "two implementations",
        subs=COMMON_SUBS + [FOLD]),
    "veach-ajar": dict(
        xml="scene_v3.xml", res=(64, 36), depth=9, tol=0.05,
        reason="the floor is a conductor with a checkerboard specular_reflectance: Mitsuba multiplies "
               "aluminium's Fresnel curve by the texture, plexus renders the colour F0*texture with "
               "Gulbrandsen's curve (its warning), which differ towards grazing angles, where the camera "
               "sees most of the floor",
        subs=COMMON_SUBS + [(r'<shape type="obj" id="(Pot2_0001|Pot2_0002|Pot3_0001|Pot3_0002|Material_0001|'
                             r'Material_0002)">.*?</shape>', '')]),
    "torus": dict(
        xml="scene.xml", res=(64, 48), depth=9, tol=0.03,
        reason="smooth glass and metal: caustics on the floor through the glass torus and off the aluminium "
               "bands, seen by pt only through the sun sphere's BSDF-sampled hits, so the noise is large",
        subs=COMMON_SUBS,
        both=[(r'<emitter type="sunsky">.*?</emitter>',
               sun_and_sky((0.48457253, -0.3902682, 0.78286666), 5000.0, 1.0, 3000.0))]),
}


def snake(name):
    out, prev = "", False
    for c in name:
        if c.isupper() and prev:
            out += "_"
        prev = c.islower() or c.isdigit()
        out += c.lower()
    return out


def plexus_scene(name, cfg):
    """The TOML plexus renders: the committed import of the original XML, or of the substituted
    XML both renderers get (scenes/crosscheck/NAME.toml, made by --write-scenes)."""
    folder = "crosscheck" if cfg.get("both") else "imported"
    return f"scenes/{folder}/{name}.toml"


def absolute_filenames(src, scene_dir):
    return re.sub(r'name="filename" value="([^"]*)"',
                  lambda m: f'name="filename" value="{os.path.join(scene_dir, m.group(1))}"', src)


def original_source(name, cfg):
    """The scene's XML with the substitutes both renderers get."""
    src = open(os.path.join(SCENE_DATA, name, cfg["xml"])).read()
    for pattern, repl in cfg.get("both", []):
        src = re.sub(pattern, lambda _m, r=repl: r, src, flags=re.S)
    return src


def write_plexus_scene(name, cfg):
    """Imports the substituted XML into scenes/crosscheck/NAME.toml (paths relative to it)."""
    plexus = os.environ.get("PLEXUS", os.path.join(ROOT, "target", "release", "plexus"))
    out = os.path.join(ROOT, plexus_scene(name, cfg))
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        xml = os.path.join(tmp, cfg["xml"])
        open(xml, "w").write(absolute_filenames(original_source(name, cfg), os.path.join(SCENE_DATA, name)))
        subprocess.run([plexus, "import", xml, "--out", out], check=True, stderr=subprocess.DEVNULL)
    original = f"scenes/mitsuba/{name}/{cfg['xml']}"
    text = open(out).read().replace(f"from {xml}", f"from {original} with the substitutes scripts/crosscheck.py "
                                    "gives both renderers (line numbers are the substituted file's)", 1)
    text = text.replace(xml, f"{original} (substituted)")
    open(out, "w").write(text)


def mitsuba_xml(name, cfg):
    """The scene's XML made loadable by Mitsuba 3 at the cross-check's settings."""
    scene_dir = os.path.join(SCENE_DATA, name)
    src = original_source(name, cfg)
    for pattern, repl in cfg["subs"]:
        src = re.sub(pattern, lambda _m, r=repl: r, src, flags=re.S)
    src = re.sub(r'name="(\w+)"', lambda m: f'name="{snake(m.group(1))}"', src)
    src = src.replace("<lookAt", "<lookat")
    src = re.sub(r'<scene version="[^"]*"', '<scene version="3.0.0"', src)
    src = re.sub(r"<default [^>]*/>", "", src)
    src = re.sub(r"<integrator .*?</integrator>",
                 f'<integrator type="path"><integer name="max_depth" value="{cfg["depth"]}"/></integrator>',
                 src, flags=re.S)
    src = re.sub(r"<sampler .*?</sampler>", "", src, flags=re.S)
    w, h = cfg["res"]
    src = re.sub(r'<integer name="width" value="[^"]*"\s*/>', f'<integer name="width" value="{w}"/>', src)
    src = re.sub(r'<integer name="height" value="[^"]*"\s*/>', f'<integer name="height" value="{h}"/>', src)
    src = re.sub(r"<rfilter [^>]*/>", '<rfilter type="box"/>', src)
    for prop in ["focus_distance", "banner", "gamma", "sampling_weight", "near_clip", "far_clip"]:
        src = re.sub(rf'<\w+ name="{prop}" value="[^"]*"\s*/>', "", src)

    def serialized(m):
        block = m.group(0)
        fname = re.search(r'name="filename" value="([^"]*)"', block).group(1)
        index = re.search(r'name="shape_index" value="(\d+)"', block)
        index = index.group(1) if index else "0"
        ply = os.path.splitext(fname)[0] + f"_{index}.ply"
        block = block.replace('type="serialized"', 'type="ply"', 1)
        block = block.replace(f'value="{fname}"', f'value="{ply}"')
        return re.sub(r'<integer name="shape_index" value="\d+"\s*/>', "", block)

    src = re.sub(r'<shape type="serialized".*?</shape>', serialized, src, flags=re.S)
    return absolute_filenames(src, scene_dir)


def luminance(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def regions(img):
    """Luminance means of the GRID x GRID regions, then of the whole image (as tests/common)."""
    lum = luminance(img)
    h, w = lum.shape
    ys = (np.arange(h) * GRID) // h
    xs = (np.arange(w) * GRID) // w
    out = []
    for gy in range(GRID):
        for gx in range(GRID):
            out.append(float(lum[np.ix_(ys == gy, xs == gx)].mean()))
    out.append(float(lum.mean()))
    return np.array(out)


def render_mitsuba(mi, xml_text, spp, renders):
    with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
        f.write(xml_text)
    scene = mi.load_file(f.name)
    os.unlink(f.name)
    imgs = [np.array(mi.render(scene, spp=spp, seed=1000 + k))[..., :3] for k in range(renders)]
    return imgs


def render_plexus(name, cfg, spp, renders, plexus_depth=None):
    plexus = os.environ.get("PLEXUS", os.path.join(ROOT, "target", "release", "plexus"))
    import mitsuba as mi
    imgs = []
    w, h = cfg["res"]
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(renders):
            out = os.path.join(tmp, f"{k}.exr")
            subprocess.run([plexus, "reference", os.path.join(ROOT, plexus_scene(name, cfg)),
                            "--integrator", "pt", "--spp", str(spp), "--seed", str(7919 * (k + 1)),
                            "--resolution", f"{w}x{h}", "--set", f"max_depth={plexus_depth or cfg['depth'] - 1}",
                            "--out", out], check=True, stderr=subprocess.DEVNULL)
            imgs.append(np.array(mi.Bitmap(out))[..., :3])
    return imgs


def stats(imgs):
    r = np.array([regions(i) for i in imgs])
    return r.mean(axis=0), r.std(axis=0, ddof=1) / math.sqrt(len(imgs))


def compare(name, cfg, pm, pse, mm, mse):
    bound = Z * np.sqrt(pse ** 2 + mse ** 2) + cfg["tol"] * mm
    diff = np.abs(pm - mm)
    worst = int(np.argmax(diff / bound))
    rel = diff / np.maximum(mm, 1e-12)
    ok = bool(np.all(diff <= bound))
    print(f"{name}: {'PASS' if ok else 'FAIL'}  image mean plexus {pm[-1]:.5g} mitsuba {mm[-1]:.5g} "
          f"({100 * (pm[-1] / mm[-1] - 1):+.2f}%), largest |diff|/bound {diff[worst] / bound[worst]:.2f} "
          f"(region {worst}), largest relative region difference {100 * rel.max():.2f}%, tolerance {cfg['tol']:.0%}")
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--renders", type=int, default=8)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--write-references", action="store_true")
    ap.add_argument("--write-scenes", action="store_true",
                    help="(re)import scenes/crosscheck/NAME.toml for scenes whose substitutes both renderers get")
    ap.add_argument("--wrong-variant", action="store_true",
                    help="also compare plexus rendered at half the depth, which must fail")
    args = ap.parse_args()
    import mitsuba as mi
    mi.set_variant(args.variant)
    all_ok = True
    for name in args.scenes.split(","):
        cfg = SCENES[name]
        if args.write_scenes and cfg.get("both"):
            write_plexus_scene(name, cfg)
        m_imgs = render_mitsuba(mi, mitsuba_xml(name, cfg), args.spp, args.renders)
        mm, mse = stats(m_imgs)
        pm, pse = stats(render_plexus(name, cfg, args.spp, args.renders))
        all_ok &= compare(name, cfg, pm, pse, mm, mse)
        if args.wrong_variant:
            wm, wse = stats(render_plexus(name, cfg, args.spp, args.renders, plexus_depth=(cfg["depth"] - 1) // 2))
            print("  wrong variant (half the depth):", end=" ")
            compare(name, cfg, wm, wse, mm, mse)
        if args.write_references:
            os.makedirs(os.path.join(ROOT, "references", "mitsuba"), exist_ok=True)
            base = os.path.join(ROOT, "references", "mitsuba", name)
            mean_img = np.mean(m_imgs, axis=0).astype(np.float32)
            mi.Bitmap(mean_img).write(base + ".exr")
            w, h = cfg["res"]
            json.dump({
                "scene": plexus_scene(name, cfg),
                "source": f"scenes/mitsuba/{name}/{cfg['xml']}",
                "renderer": f"Mitsuba {mi.MI_VERSION} ({args.variant}), integrator path",
                "mitsuba_max_depth": cfg["depth"], "plexus_max_depth": cfg["depth"] - 1,
                "resolution": [w, h], "spp": args.spp, "renders": args.renders,
                "seeds": [1000 + k for k in range(args.renders)],
                "grid": GRID, "region_means": list(mm), "region_std_errors": list(mse),
                "tolerance": cfg["tol"], "tolerance_reason": cfg["reason"],
                "substitutions_mitsuba": [p for p, _ in cfg["subs"]],
                "substitutions_both": [{"pattern": p, "replacement": r} for p, r in cfg.get("both", [])],
                "made_by": " ".join(["scripts/crosscheck.py"] + sys.argv[1:]),
            }, open(base + ".json", "w"), indent=1)
    sys.exit(0 if all_ok else 1)


if __name__ == "__main__":
    main()
