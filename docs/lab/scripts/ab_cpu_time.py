#!/usr/bin/env python3
"""CPU seconds per image of plexus binaries and Mitsuba 3 variants on one scene, interleaved (issue 20).

On a shared machine wall-clock times move with the other users' load; CPU seconds move much less,
and renders interleaved round by round see the same load drift. Each contestant renders the same
XML (scripts/peers.py's `scene_xml`: the scene as the peers table renders it) at the same samples
per pixel and thread count; a round renders each contestant once with the round's seed, and the
script prints per contestant the median CPU seconds of the render, and the median of the per-round
ratios to the first contestant.

What is timed is the render alone, not loading or compiling:
- plexus: `cpu_time_s` of its render JSON (the render's CPU time, all threads);
- Mitsuba: `time.process_time()` around `mi.render` in a worker process that loaded the scene and
  rendered twice before the first timed render (kernel compilation; the first render after it still
  took about twice as long, see peers.py `warm_up`). process_time counts all the process's threads,
  Dr.Jit's workers included.

    /work/peersenv/bin/python docs/lab/scripts/ab_cpu_time.py --scene veach-ajar --spp 64 --threads 1 --rounds 7 \\
        --plexus target/release/plexus --mitsuba llvm_ad_rgb --mitsuba scalar_rgb
    # A/B of two plexus builds (the first is the base of the ratios):
    /work/peersenv/bin/python docs/lab/scripts/ab_cpu_time.py --plexus /tmp/base/plexus --plexus target/release/plexus

llvm_ad_rgb needs libLLVM: DRJIT_LIBLLVM_PATH, else Debian's libLLVM-19.so where peers.sh looks. The load average is printed before
and after.
"""
import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))

WORKER = r"""
import sys, time
import mitsuba as mi, drjit as dr
variant, xml, spp, threads = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
mi.set_variant(variant)
dr.set_thread_count(threads)
scene = mi.load_file(xml)
for seed in (999999, 999998):
    mi.render(scene, spp=spp, seed=seed).numpy()
print("ready", flush=True)
for line in sys.stdin:
    seed = int(line)
    c, t = time.process_time(), time.perf_counter()
    mi.render(scene, spp=spp, seed=seed).numpy()
    print(time.process_time() - c, time.perf_counter() - t, flush=True)
"""


def find_libllvm():
    """DRJIT_LIBLLVM_PATH as scripts/peers.sh sets it: the environment's, else Debian's libLLVM-19."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return
    for lib in ["/usr/lib/x86_64-linux-gnu/libLLVM-19.so", "/usr/lib/llvm-19/lib/libLLVM-19.so"]:
        if os.path.exists(lib):
            os.environ["DRJIT_LIBLLVM_PATH"] = lib


class Mitsuba:
    """A worker process holding the loaded, warmed-up scene in one variant; renders on request."""

    def __init__(self, variant, xml, spp, threads):
        self.name = f"Mitsuba {variant}"
        self.proc = subprocess.Popen([sys.executable, "-c", WORKER, variant, xml, str(spp), str(threads)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        if line.strip() != "ready":
            sys.exit(f"ab_cpu_time.py: the {variant} worker did not start")

    def render(self, seed):
        self.proc.stdin.write(f"{seed}\n")
        self.proc.stdin.flush()
        cpu, wall = (float(v) for v in self.proc.stdout.readline().split())
        return cpu, wall

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


class Plexus:
    """One plexus binary rendering the XML with pt (max_depth = Mitsuba's depth - 1)."""

    def __init__(self, binary, xml, spp, threads, depth, sampler, tmp, index):
        self.name = f"plexus {binary}"
        self.cmd = [binary, "render", xml, "--integrator", "pt", "--spp", str(spp), "--threads", str(threads),
                    "--set", f"max_depth={depth}", "--set", f'sampler="{sampler}"']
        self.out = os.path.join(tmp, f"plexus{index}.exr")

    def render(self, seed):
        subprocess.run(self.cmd + ["--seed", str(seed), "-o", self.out], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        stats = json.load(open(os.path.splitext(self.out)[0] + ".json"))
        return stats["cpu_time_s"], stats["wall_time_s"]

    def close(self):
        pass


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="veach-ajar", help="a scene of scripts/peers.py")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--depth", type=int, default=16, help="plexus max_depth; Mitsuba gets one more")
    ap.add_argument("--sampler", default="sobol", help="plexus's sampler")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--plexus", action="append", default=[], help="a plexus binary (repeatable)")
    ap.add_argument("--mitsuba", action="append", default=[], help="a Mitsuba 3 variant (repeatable)")
    args = ap.parse_args()
    spec = importlib.util.spec_from_file_location("peers", os.path.join(ROOT, "scripts", "peers.py"))
    peers = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(peers)
    xml_text = peers.scene_xml(peers.load_crosscheck(), args.scene, args.depth + 1)
    find_libllvm()
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        xml = os.path.join(tmp, "scene.xml")
        open(xml, "w").write(xml_text)
        contestants = [Plexus(b, xml, args.spp, args.threads, args.depth, args.sampler, tmp, i)
                       for i, b in enumerate(args.plexus)]
        contestants += [Mitsuba(v, xml, args.spp, args.threads) for v in args.mitsuba]
        times = [[] for _ in contestants]
        for r in range(args.rounds):
            for c, t in zip(contestants, times):
                t.append(c.render(1 + r))
            print(f"round {r + 1}: " + ", ".join(f"{t[-1][0]:.3f}" for t in times), file=sys.stderr, flush=True)
        for c in contestants:
            c.close()
    cpu = np.array([[x[0] for x in t] for t in times])
    wall = np.array([[x[1] for x in t] for t in times])
    print(f"| contestant | median CPU s | median wall s | median per-round CPU ratio to the first | range of the ratio |")
    print("| --- | ---: | ---: | ---: | --- |")
    for i, c in enumerate(contestants):
        ratio = cpu[i] / cpu[0]
        print(f"| {c.name} | {np.median(cpu[i]):.3f} | {np.median(wall[i]):.3f} | {np.median(ratio):.3f} "
              f"| {ratio.min():.3f}–{ratio.max():.3f} |")
    print(f"\n{args.scene}, {args.spp} spp, {args.threads} thread(s), {args.rounds} rounds, plexus sampler "
          f"{args.sampler}; load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after.")


if __name__ == "__main__":
    main()
