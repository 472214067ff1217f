#!/usr/bin/env python3
"""Second-Ctrl-C stress: does a render interrupted twice leave anything but complete outputs?

tests/commands/interrupt.rs `a_second_interrupt_exits_and_leaves_only_complete_outputs` signals five
renders; the races it guards against are rare (about one run in a hundred before session 20), so
this script repeats its protocol many times: a render of the tests' tiny scene (256x192, one
thread, max_depth 1, a preview written after every pass), SIGINT at 0..34 ms after the first
preview, a second SIGINT 5 ms later. A run fails if the process exits with other than 130 or
leaves any file but o.exr, o.png, o.json, o.pxstate. Binaries are alternated run by run, so that
the machine's load falls on all alike. Also reports how long the second signal took to end the
process.

Usage: scripts/stress_second_interrupt.py RUNS BINARY [BINARY ...]
"""
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUTPUTS = {"o.exr", "o.png", "o.json", "o.pxstate"}


def tiny_scene():
    """The tests' TINY_SCENE (tests/common/binary.rs) at 256x192 with no extra shapes."""
    src = open(os.path.join(ROOT, "tests", "common", "binary.rs")).read()
    body = re.search(r'const TINY_SCENE: &str = r#"(.*?)"#;', src, re.S).group(1)
    return body.replace("{RESOLUTION}", "[256, 192]").replace("{EXTRA}", "")


def one_run(binary, work, delay_s):
    """One render interrupted twice; returns (exit code, stderr tail, files left over, seconds from
    the second signal to the exit)."""
    out = os.path.join(work, "out")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    p = subprocess.Popen([binary, "render", "../s.toml", "--time", "1000", "--threads", "1", "--set", "max_depth=1",
                          "--out", "o.exr", "--out", "o.png", "--preview-every", "1e-9"], cwd=out,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    while not os.path.exists(os.path.join(out, "o.png")):
        time.sleep(0.001)
    time.sleep(delay_s)
    p.send_signal(signal.SIGINT)
    # Apart, so that the kernel does not merge them into one pending signal.
    time.sleep(0.005)
    t = time.monotonic()
    p.send_signal(signal.SIGINT)
    _, err = p.communicate()
    took = time.monotonic() - t
    left = sorted(set(os.listdir(out)) - OUTPUTS)
    return p.returncode, err.decode(errors="replace")[-300:], left, took


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    runs, binaries = int(sys.argv[1]), [os.path.abspath(b) for b in sys.argv[2:]]
    failed = {b: 0 for b in binaries}
    took = {b: [] for b in binaries}
    with tempfile.TemporaryDirectory(prefix="plexus-stress-") as work:
        open(os.path.join(work, "s.toml"), "w").write(tiny_scene())
        for run in range(runs):
            for b in binaries:
                code, err, left, t = one_run(b, work, 0.001 * (run % 35))
                took[b].append(t)
                if code != 130 or left:
                    failed[b] += 1
                    print(f"{b}: run {run}: exit {code}, left {left} {err if code != 130 else ''}", flush=True)
    for b in binaries:
        t = sorted(took[b])
        print(f"{b}: {runs} runs, {failed[b]} failed; second signal to exit: median {t[len(t) // 2] * 1e3:.1f} ms, "
              f"max {t[-1] * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
