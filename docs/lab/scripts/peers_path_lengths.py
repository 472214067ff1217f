#!/usr/bin/env python3
"""Rays per sample, shadow rays and path lengths of Mitsuba 3's `path` integrator, against plexus pt
(issue 20: is the door's 0.55x efficiency the estimator or the time per ray?).

Mitsuba reports no ray counts, so this script renders with a Python mirror of Mitsuba 3.9's `path`
integrator (src/integrators/path.cpp and Scene::sample_emitter_direction in src/render/scene.cpp),
written with Mitsuba's own Python API in the `scalar_rgb` variant: the same calls
(`scene.ray_intersect`, `scene.sample_emitter_direction`, `bsdf.eval_pdf_sample`,
`scene.pdf_emitter_direction`, `emitter.eval`) in the same order, drawing the same random numbers
from the same sampler, and counting what it does:

- bounce rays: closest-hit queries (the camera ray and each BSDF-sampled continuation);
- shadow rays: occlusion queries. Mitsuba traces one at every vertex that samples an emitter (a
  surface with a smooth lobe, not at the last depth) whenever the emitter sample's density is not
  zero (Scene::sample_emitter_direction with test_visibility), *before* the BSDF is evaluated and
  whether or not the emitter faces the point; they are split below by what plexus does with the
  same sample: plexus traces one only when the emitter faces the point and the BSDF value there is
  not zero (src/integrator/pt.rs), so the split says where the two counts differ. The mirror makes
  path.cpp's own call (test_visibility on) and repeats the sample without the test, tracing that
  ray itself: at every vertex Mitsuba's call must have zeroed the sample exactly when this ray is
  occluded (mismatches are counted and must be 0), and back-facing samples that Mitsuba's call
  found occluded show that it traces those rays too;
- path lengths: the histogram of bounce rays per sample, and how paths end (escaped, maximum depth,
  Russian roulette, zero throughput);
- Russian roulette: rolls, and rolls where Mitsuba's 0.95 cap on the survival probability
  q = min(max(throughput) * eta^2, 0.95) was active (plexus rolls with q < 1 uncapped and does not
  roll at q >= 1).

Validation (the mirror is the estimator it claims to be): the mirror is registered as a Mitsuba
integrator (`path_mirror`) and rendered through Mitsuba's own render loop, so the camera rays and the
sampler (independent, seeded as `mi.render(seed=...)` seeds it) are Mitsuba's. With the same scene,
seed and samples per pixel it then draws exactly the random numbers Mitsuba's compiled `path` draws,
and its image must equal `path`'s pixel for pixel up to float rounding (Python's arithmetic on the
returned values versus C++'s fused operations): the script prints the relative difference of the
image means, the largest per-pixel difference and the share of pixels that differ. Any difference
in the algorithm (which numbers are drawn, the MIS weights, the roulette rule) changes whole paths
and shows as differences far above rounding in many pixels: the negative control (--check-control)
renders the mirror with the balance heuristic in place of the power heuristic, an unbiased estimator
of the same image that differs from `path` only in its MIS weights.

`--plexus` also renders the same XML with plexus (`plexus render FILE.xml --integrator pt`, both
samplers, max_depth = Mitsuba's depth - 1: plexus counts bounces, Mitsuba path edges) and reads the
rays and shadow rays per sample from its render JSON (`counters`; plexus does not report path
lengths).

Run it with the Python of the peers venv (scripts/peers.sh makes one; scalar_rgb needs no libLLVM):

    target/peersenv/bin/python docs/lab/scripts/peers_path_lengths.py [--scenes veach-ajar,...] [--res 160x90]
        [--spp 16] [--depth 16] [--seed 1] [--plexus] [--check-control]

Scenes, XML and depth convention are scripts/peers.py's (`scene_xml`), and so are the resolutions
unless --res is given (the mirror runs a sample in about 0.2 ms of Python: 16 spp at 160x90 take
about a minute).
"""
import argparse
import collections
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))


def load_peers():
    """scripts/peers.py as a module (its scene list and `scene_xml`)."""
    spec = importlib.util.spec_from_file_location("peers", os.path.join(ROOT, "scripts", "peers.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Tally:
    """What one worker thread's paths did (merged after the render; one per thread, so that Mitsuba's
    render threads never update the same counters)."""

    def __init__(self, max_depth):
        self.samples = 0
        self.bounce_rays = 0
        self.shadow_rays = 0
        # The shadow rays by what plexus would have done with the same emitter sample.
        self.shadow_back = 0  # the emitter faces away from the point (its value is zero): plexus traces none
        self.shadow_bsdf_zero = 0  # emitter faces the point, BSDF value zero (light below the surface): none
        self.shadow_both = 0  # both non-zero: plexus traces one too
        self.nee_vertices = 0  # vertices that sampled an emitter (a smooth lobe, not the last depth)
        self.vertices = 0  # surface hits
        self.lengths = np.zeros(max_depth + 2, dtype=np.int64)  # bounce rays per sample
        self.ends = collections.Counter()
        # Checks of the shadow-ray rule against Mitsuba's own sample_emitter_direction: samples where
        # its occlusion result and this script's ray_test disagree (must be 0), and back-facing
        # samples it found occluded (> 0 shows that it tests them).
        self.rule_mismatches = 0
        self.back_occluded = 0
        self.rr_rolls = 0
        self.rr_capped = 0  # rolls where min(..., 0.95) changed q (max(throughput) * eta^2 > 0.95)
        self.rr_no_roll_in_plexus = 0  # rolls where max(throughput) * eta^2 >= 1: plexus does not roll

    def merge(self, o):
        for k, v in vars(o).items():
            if k == "ends":
                self.ends.update(v)
            else:
                setattr(self, k, getattr(self, k) + v)


def mirror_integrator_class(mi, dr):
    """The `path_mirror` integrator class for the current variant (scalar_rgb)."""

    def mis_weight(pdf_a, pdf_b, balance=False):
        """path.cpp's power heuristic (or, for the negative control, the balance heuristic), 0 where
        not finite."""
        a, b = (pdf_a, pdf_b) if balance else (pdf_a * pdf_a, pdf_b * pdf_b)
        w = a / (a + b) if (a + b) != 0 else float("nan")
        return w if np.isfinite(w) else 0.0

    class PathMirror(mi.SamplingIntegrator):
        """Mitsuba 3.9's `path` (surfaces only, no hidden emitters, no AOVs), step for step."""

        def __init__(self, props):
            super().__init__(props)
            self.max_depth = props.get("max_depth", 17)
            self.rr_depth = props.get("rr_depth", 5)
            self.rr_cap = props.get("rr_cap", 0.95)
            # The negative control: the balance heuristic instead of path.cpp's power heuristic.
            self.balance = props.get("balance", False)
            self.tallies = {}
            self.lock = threading.Lock()

        def tally(self):
            ident = threading.get_ident()
            t = self.tallies.get(ident)
            if t is None:
                with self.lock:
                    t = self.tallies.setdefault(ident, Tally(self.max_depth))
            return t

        def merged(self):
            total = Tally(self.max_depth)
            for t in self.tallies.values():
                total.merge(t)
            return total

        def sample(self, scene, sampler, ray_, medium=None, active=True):
            tally = self.tally()
            tally.samples += 1
            ctx = mi.BSDFContext()
            ray = mi.Ray3f(ray_)
            throughput = mi.Color3f(1.0)
            result = mi.Color3f(0.0)
            eta = 1.0
            depth = 0
            valid_ray = False
            prev_si = dr.zeros(mi.Interaction3f)
            prev_bsdf_pdf = 1.0
            prev_bsdf_delta = True
            rays = 0
            end = None
            while True:
                si = scene.ray_intersect(ray)
                rays += 1
                valid = bool(si.is_valid())
                # Direct emission: an emitter hit by the camera ray or a BSDF-sampled ray.
                emitter = si.emitter(scene)
                if emitter is not None:
                    ds = mi.DirectionSample3f(scene, si, prev_si)
                    em_pdf = 0.0
                    if not prev_bsdf_delta:
                        em_pdf = scene.pdf_emitter_direction(prev_si, ds, True)
                    mis_bsdf = mis_weight(prev_bsdf_pdf, em_pdf, self.balance)
                    contrib = ds.emitter.eval(si, prev_bsdf_pdf > 0.0) * mis_bsdf
                    result = dr.fma(throughput, contrib, result)
                active_next = (depth + 1 < self.max_depth) and valid
                if not active_next:
                    valid_ray |= emitter is not None
                    end = "escaped" if not valid else "max depth"
                    break
                tally.vertices += 1
                bsdf = si.bsdf(ray)
                # Emitter sampling (next-event estimation) at vertices with a smooth lobe.
                active_em = mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
                wo = mi.Vector3f(0.0)
                em_weight = mi.Color3f(0.0)
                ds = None
                if active_em:
                    tally.nee_vertices += 1
                    u = sampler.next_2d()
                    # path.cpp's call: Scene::sample_emitter_direction with test_visibility, which
                    # traces an occlusion ray whenever the sample's pdf is not zero and sets the pdf
                    # and value to zero if it is occluded.
                    ds, em_weight = scene.sample_emitter_direction(si, u, True, True)
                    # The same sample without the test, and that test done here, to count the ray
                    # and to check the rule at every vertex: the call above zeroed the pdf exactly
                    # when this ray is occluded, back-facing emitter samples included.
                    ds0, weight0 = scene.sample_emitter_direction(si, u, False, True)
                    if ds0.pdf != 0.0:
                        tally.shadow_rays += 1
                        facing = bool(dr.any(weight0 != 0.0))
                        occluded = bool(scene.ray_test(si.spawn_ray_to(ds0.p), True))
                        tally.rule_mismatches += occluded != (ds.pdf == 0.0)
                        tally.back_occluded += occluded and not facing
                    active_em = ds.pdf != 0.0
                    wo = si.to_local(ds.d)
                sample_1 = sampler.next_1d()
                sample_2 = sampler.next_2d()
                bsdf_val, bsdf_pdf, bs, bsdf_weight = bsdf.eval_pdf_sample(ctx, si, wo, sample_1, sample_2)
                if ds is not None and ds0.pdf != 0.0:
                    # Split of the shadow ray by what plexus does with the same sample.
                    if not facing:
                        tally.shadow_back += 1
                    elif not bool(dr.any(bsdf_val != 0.0)):
                        tally.shadow_bsdf_zero += 1
                    else:
                        tally.shadow_both += 1
                if active_em:
                    mis_em = 1.0 if ds.delta else mis_weight(ds.pdf, bsdf_pdf, self.balance)
                    result = dr.fma(throughput, bsdf_val * em_weight * mis_em, result)
                # BSDF sampling: the continuation.
                ray = si.spawn_ray(si.to_world(bs.wo))
                throughput = throughput * bsdf_weight
                eta *= bs.eta
                valid_ray |= valid and not mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null)
                prev_si = mi.Interaction3f(si)
                prev_bsdf_pdf = bs.pdf
                prev_bsdf_delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
                if valid:
                    depth += 1
                # Russian roulette (drawn at every vertex; applied from depth rr_depth on).
                throughput_max = float(dr.max(throughput))
                m = throughput_max * eta * eta
                rr_prob = min(m, self.rr_cap)
                rr_active = depth >= self.rr_depth
                rr_continue = sampler.next_1d() < rr_prob
                if rr_active:
                    # rcp(0) is inf in Mitsuba; q = 0 only when the throughput is 0, and the path ends.
                    throughput = throughput * (1.0 / rr_prob if rr_prob > 0.0 else float("inf"))
                    tally.rr_rolls += 1
                    tally.rr_capped += m > self.rr_cap
                    tally.rr_no_roll_in_plexus += m >= 1.0
                if throughput_max == 0.0:
                    end = "zero throughput"
                    break
                if rr_active and not rr_continue:
                    end = "roulette"
                    break
            tally.bounce_rays += rays
            tally.lengths[min(rays, len(tally.lengths) - 1)] += 1
            tally.ends[end] += 1
            return (result if valid_ray else mi.Color3f(0.0)), valid_ray, []

    return PathMirror


def with_integrator(xml, integrator):
    """The scene XML with its integrator block replaced by `integrator` (XML text)."""
    import re
    return re.sub(r"<integrator .*?</integrator>", integrator, xml, count=1, flags=re.S)


def load_scene(mi, xml):
    with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
        f.write(xml)
    try:
        return mi.load_file(f.name)
    finally:
        os.unlink(f.name)


def render_plexus_counts(xml_path, spp, depth, seed, sampler, tmp):
    """plexus pt on the same XML: (bounce rays, shadow rays) per sample from its render JSON."""
    plexus = os.environ.get("PLEXUS", os.path.join(ROOT, "target", "release", "plexus"))
    out = os.path.join(tmp, f"plexus-{sampler}.exr")
    subprocess.run([plexus, "render", xml_path, "--integrator", "pt", "--spp", str(spp), "--seed", str(seed),
                    "--threads", "2", "--set", f"max_depth={depth}", "--set", f'sampler="{sampler}"', "-o", out],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    stats = json.load(open(os.path.splitext(out)[0] + ".json"))
    c = stats["counters"]
    return c["rays"] / c["samples"], c["shadow_rays"] / c["samples"]


def compare_images(a, b):
    """(relative difference of the image means, largest |a - b| relative to b's mean, share of
    pixel channels that differ)."""
    rel_mean = float(a.mean() / b.mean() - 1.0)
    max_abs = float(np.abs(a - b).max() / b.mean())
    differ = float(np.mean(a != b))
    return rel_mean, max_abs, differ


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="cornell-box,cornell-glossy,cornell-glass,veach-ajar")
    ap.add_argument("--res", help="resolution WxH for every scene (default: peers.py's, 128x128 and the door 160x90)")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--depth", type=int, default=16, help="plexus max_depth (bounces); Mitsuba gets one more")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--plexus", action="store_true", help="also run plexus on the same XML and read its counts")
    ap.add_argument("--check-control", action="store_true",
                    help="also render the mirror with the balance heuristic, which must differ from path")
    ap.add_argument("--json", metavar="FILE", help="write the figures as JSON")
    args = ap.parse_args()
    import mitsuba as mi
    import drjit as dr
    mi.set_variant("scalar_rgb")
    # Mitsuba warns, on stdout, that Python integrators are slow in scalar variants: known, and the
    # table goes to stdout.
    mi.set_log_level(mi.LogLevel.Error)
    dr.set_thread_count(args.threads)
    mi.register_integrator("path_mirror", lambda props: mirror_integrator_class(mi, dr)(props))
    peers = load_peers()
    cc = peers.load_crosscheck()
    mdepth = args.depth + 1
    results = {}
    for name in args.scenes.split(","):
        res = tuple(int(v) for v in args.res.split("x")) if args.res else None
        xml = peers.scene_xml(cc, name, mdepth, res=res)
        row = dict(res=res or peers.variants(cc)[name]["res"], spp=args.spp, seed=args.seed, mitsuba_depth=mdepth)
        # Mitsuba's own `path`, then the mirror, same seed and samples: the validation.
        scene = load_scene(mi, xml)
        reference = np.array(mi.render(scene, spp=args.spp, seed=args.seed), dtype=np.float64)[..., :3]
        mirror_xml = with_integrator(xml, f'<integrator type="path_mirror"><integer name="max_depth" '
                                          f'value="{mdepth}"/></integrator>')
        scene = load_scene(mi, mirror_xml)
        t0 = time.perf_counter()
        image = np.array(mi.render(scene, spp=args.spp, seed=args.seed), dtype=np.float64)[..., :3]
        row["python_seconds"] = time.perf_counter() - t0
        row["validation"] = compare_images(image, reference)
        t = scene.integrator().merged()
        n = t.samples
        row.update(samples=n, bounce_rays=t.bounce_rays / n, shadow_rays=t.shadow_rays / n,
                   shadow_back=t.shadow_back / n, shadow_bsdf_zero=t.shadow_bsdf_zero / n,
                   shadow_both=t.shadow_both / n, vertices=t.vertices / n, nee_vertices=t.nee_vertices / n,
                   lengths=(t.lengths / n).tolist(), ends={k: v / n for k, v in t.ends.items()},
                   rule_mismatches=t.rule_mismatches, back_occluded=t.back_occluded, shadow_total=t.shadow_rays,
                   rr_rolls=t.rr_rolls / n, rr_capped=t.rr_capped / n, rr_no_roll_in_plexus=t.rr_no_roll_in_plexus / n)
        if args.check_control:
            control_xml = with_integrator(xml, f'<integrator type="path_mirror"><integer name="max_depth" '
                                               f'value="{mdepth}"/><boolean name="balance" value="true"/></integrator>')
            control = np.array(mi.render(load_scene(mi, control_xml), spp=args.spp, seed=args.seed),
                               dtype=np.float64)[..., :3]
            row["control"] = compare_images(control, reference)
        if args.plexus:
            with tempfile.TemporaryDirectory() as tmp:
                path = os.path.join(tmp, "scene.xml")
                open(path, "w").write(xml)
                for sampler in ("sobol", "independent"):
                    row[f"plexus_{sampler}"] = render_plexus_counts(path, args.spp, args.depth, args.seed, sampler, tmp)
        results[name] = row
        print(summary(name, row), file=sys.stderr, flush=True)
    print(tables(results, args))
    if args.json:
        json.dump(results, open(args.json, "w"), indent=1)


def summary(name, r):
    v = r["validation"]
    text = (f"{name}: {r['samples']} samples in {r['python_seconds']:.0f} s; mirror vs path: image mean "
            f"{v[0]:+.2e}, largest pixel difference {v[1]:.2e} of the mean, {100 * v[2]:.3f}% of values differ")
    text += (f"; shadow-ray rule: {r['rule_mismatches']} mismatches in {r['shadow_total']} rays, "
             f"{r['back_occluded']} back-facing samples found occluded by Mitsuba's own test")
    if "control" in r:
        c = r["control"]
        text += f"; control (balance heuristic): {c[0]:+.2e}, {c[1]:.2e}, {100 * c[2]:.1f}% differ"
    return text


def tables(results, args):
    """Markdown tables: rays per sample side by side; Mitsuba's path lengths and ends."""
    out = ["| scene | Mitsuba bounce rays / sample | plexus (Sobol, independent) | Mitsuba shadow rays / sample "
           "| of which: emitter faces away; BSDF zero; both non-zero | plexus shadow rays / sample (Sobol, independent) "
           "| Mitsuba roulette rolls / sample, capped at 0.95 | validation: image mean, largest pixel diff, values differing |",
           "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for name, r in results.items():
        ps = r.get("plexus_sobol")
        pi = r.get("plexus_independent")
        pb = f"{ps[0]:.3f}, {pi[0]:.3f}" if ps else "–"
        psh = f"{ps[1]:.3f}, {pi[1]:.3f}" if ps else "–"
        v = r["validation"]
        out.append(f"| {name} | {r['bounce_rays']:.3f} | {pb} | {r['shadow_rays']:.3f} | {r['shadow_back']:.3f}; "
                   f"{r['shadow_bsdf_zero']:.3f}; {r['shadow_both']:.3f} | {psh} | {r['rr_rolls']:.3f}, "
                   f"{r['rr_capped']:.4f} | {v[0]:+.1e}, {v[1]:.1e}, {100 * v[2]:.2f}% |")
    out += ["", "| scene | " + " | ".join(f"{k} rays" for k in range(1, args.depth + 3)) + " | ends: escaped, max depth, "
            "roulette, zero throughput |", "| --- |" + " ---: |" * (args.depth + 3)]
    for name, r in results.items():
        e = r["ends"]
        ends = ", ".join(f"{e.get(k, 0.0):.3f}" for k in ("escaped", "max depth", "roulette", "zero throughput"))
        out.append(f"| {name} | " + " | ".join(f"{x:.4f}" for x in r["lengths"][1:]) + f" | {ends} |")
    first = next(iter(results.values()))
    out.append(f"\n{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, `docs/lab/scripts/peers_path_lengths.py --res "
               f"{args.res or 'peers.py'} --spp {args.spp} --depth {args.depth} --seed {args.seed}"
               f"{' --plexus' if args.plexus else ''}`; Mitsuba scalar_rgb mirror, {first['spp']} spp; load average "
               f"{os.getloadavg()[0]:.1f}.")
    return "\n".join(out)


if __name__ == "__main__":
    main()
