#!/usr/bin/env python3
"""Depth 0 outside the chains (`direct_emission`): MMLT and RJMLT with depth 0 rendered by the
camera estimator ("camera") and in the chains ("chains"), and pt, at equal time against a
path-traced reference, interleaved by seed (each seed renders every configuration in turn, so
that the shared machine's changing load falls on all of them alike).

Per render: MSE (mean over pixels and channels of (a - b)^2, as `plexus compare` and `converge`
compute it) on the whole image and on the rows below the light (every row below the lowest row
that holds a pixel of an emitter seen directly: in the reference, luminance above half its
maximum; no such region when no emitter is in view), relMSE on the whole image, the mutations and
the camera estimator's share of the rays and of the passes' time (`integrator_stats.direct_emission`).
The table gives per configuration the median over seeds and the median of the per-seed MSE ratios
to pt and to the same method's "chains" configuration.

    python3 docs/lab/scripts/bench_depth0.py --plexus target/release/plexus --scene scenes/veach-ajar.toml \\
        --resolution 160x90 --max-depth 8 --time 10 --seeds 3 --reference REF.exr --out-dir DIR

Needs numpy and the OpenEXR Python module. The reference is a pt render of the same scene at the
same resolution and max depth (`plexus reference SCENE --spp N --resolution WxH --set max_depth=D`).
"""
import argparse
import json
import os
import statistics
import subprocess

import numpy as np
import OpenEXR

CONFIGS = [
    ("pt", "pt", []),
    ("mmlt camera", "mmlt", ['direct_emission="camera"']),
    ("mmlt chains", "mmlt", ['direct_emission="chains"']),
    ("rjmlt camera", "rjmlt", ['direct_emission="camera"']),
    ("rjmlt chains", "rjmlt", ['direct_emission="chains"']),
]


def read_exr(path):
    with OpenEXR.File(path) as f:
        channels = f.channels()
        if "RGB" in channels:
            return np.asarray(channels["RGB"].pixels, dtype=np.float64)
        return np.stack([np.asarray(channels[c].pixels, dtype=np.float64) for c in "RGB"], axis=-1)


def luminance(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def below_light_rows(reference):
    """The first row below the lowest row holding an emitter seen directly, or None."""
    lum = luminance(reference)
    rows = np.nonzero((lum > 0.5 * lum.max()).any(axis=1))[0]
    if lum.max() <= 0 or len(rows) == 0 or rows[-1] + 1 >= lum.shape[0]:
        return None
    return int(rows[-1]) + 1


def render(args, name, integrator, settings, seed):
    out = os.path.join(args.out_dir, f"{name.replace(' ', '-')}-{seed}.exr")
    sets = [a for kv in [f"max_depth={args.max_depth}", *settings] for a in ("--set", kv)]
    subprocess.run([args.plexus, "reference", args.scene, "--integrator", integrator, "--time", str(args.time),
                    "--seed", str(seed), "--threads", str(args.threads), "--resolution", args.resolution, *sets,
                    "--out", out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    stats = json.load(open(out[:-4] + ".json"))
    return read_exr(out), stats


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plexus", required=True)
    p.add_argument("--scene", required=True)
    p.add_argument("--resolution", required=True)
    p.add_argument("--max-depth", type=int, default=8)
    p.add_argument("--time", type=float, default=10)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--reference", required=True)
    p.add_argument("--out-dir", required=True)
    args = p.parse_args()
    reference = read_exr(args.reference)
    y0 = below_light_rows(reference)
    rows = []
    for seed in range(args.seeds):
        for name, integrator, settings in CONFIGS:
            img, stats = render(args, name, integrator, settings, seed)
            err = (img - reference) ** 2
            st = stats.get("integrator_stats") or {}
            direct = st.get("direct_emission") or {}
            rows.append({
                "config": name, "seed": seed, "wall": stats["wall_time_s"],
                "mse": float(err.mean()),
                "mse_below": float(err[y0:].mean()) if y0 is not None else float("nan"),
                "relmse": float((err / (reference ** 2 + 1e-2)).mean()),
                "mutations": st.get("mutations", stats.get("samples")),
                "ray_share": direct.get("share_of_rays"), "time_share": direct.get("share_of_pass_time"),
                "depth0_iterations": (st.get("per_depth") or [{}])[0].get("iterations"),
            })
            print(json.dumps(rows[-1]), flush=True)
    with open(os.path.join(args.out_dir, "rows.json"), "w") as f:
        json.dump({"below_light_from_row": y0, "rows": rows}, f, indent=1)

    def per_seed(config, key):
        return [r[key] for r in rows if r["config"] == config]

    def median_ratio(a, b, key):
        return statistics.median(x / y for x, y in zip(per_seed(a, key), per_seed(b, key)))

    print(f"\nbelow the light: rows {y0} and below" if y0 is not None else "\nno emitter in view")
    print("| configuration | MSE | MSE below the light | relMSE | MSE ÷ pt's | below ÷ pt's | MSE ÷ chains' "
          "| below ÷ chains' | mutations | camera share of rays / pass time |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name, integrator, _ in CONFIGS:
        med = lambda key: statistics.median(per_seed(name, key))  # noqa: E731
        chains = f"{integrator} chains"
        vs_chains = name.endswith("camera")
        share = per_seed(name, "ray_share")
        share_text = (f"{statistics.median(share):.1%} / {statistics.median(per_seed(name, 'time_share')):.1%}"
                      if share and share[0] is not None else "")
        print(f"| {name} | {med('mse'):.4g} | {med('mse_below'):.4g} | {med('relmse'):.4g} "
              f"| {median_ratio(name, 'pt', 'mse'):.3g} | {median_ratio(name, 'pt', 'mse_below'):.3g} "
              f"| {median_ratio(name, chains, 'mse') if vs_chains else float('nan'):.3g} "
              f"| {median_ratio(name, chains, 'mse_below') if vs_chains else float('nan'):.3g} "
              f"| {med('mutations'):.3g} | {share_text} |")


if __name__ == "__main__":
    main()
