"""plexus-batch on real LocalClusters with the real `plexus` binary (target/release/plexus, or
$PLEXUS_BIN): the images a batch produces do not depend on how many workers ran it, on a worker
dying in the middle, or on another job of the batch failing.

"The same image" is bit for bit: the EXR's pixel data (everything after the header, compared as
bytes) and its header attributes but the capture date, and the PNG's bytes.

One batch of three jobs (pt, bdpt and MMLT on small Cornell boxes, 2 or 3 shards each) is rendered
three times: the reference on one worker, on two workers, and on two workers of which one is killed
while a shard runs on it; then its first job and a broken one run on a running scheduler.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import psutil
import pytest
from distributed import Client, LocalCluster

from plexus_batch import load, run_batch

REPO = Path(__file__).resolve().parents[2]
PLEXUS = Path(os.environ.get("PLEXUS_BIN", REPO / "target" / "release" / "plexus"))

# Small: the four batch runs should take seconds. A shard still runs for about a second (most of it
# the binary's start), long enough for the kill test to find one running.
RESOLUTION = "[32, 32]"
# A pass of pt and bdpt holds about 2^16 pixel samples, 64 per pixel at 32x32, and a shard is a set
# of passes (plexus refuses a shard beyond the passes): pt's 192 spp are 3 passes for its 3 shards,
# bdpt's 128 are 2 for its 2, so every shard renders.

BATCH = """
shard_dir = "shards"

[[jobs]]
name = "box-pt"
scene = "scenes/cornell-box.toml"
integrator = "pt"
spp = 192
seed = 3
shards = 3
outputs = ["out/box-pt.exr", "out/box-pt.png"]

[[jobs]]
name = "glossy-bdpt"
scene = "scenes/cornell-glossy.toml"
integrator = "bdpt"
spp = 128
seed = 5
shards = 2
settings = { max_depth = 6 }
outputs = ["out/glossy-bdpt.exr"]

[[jobs]]
name = "glass-mmlt"
scene = "scenes/cornell-glass.toml"
integrator = "mmlt"
spp = 8
seed = 7
shards = 2
settings = { max_depth = 6, bootstrap = 5000, chains = 32 }
outputs = ["out/glass-mmlt.exr"]
"""

BAD_JOB = """
[[jobs]]
name = "broken"
scene = "scenes/broken.toml"
integrator = "pt"
spp = 8
shards = 2
outputs = ["out/broken.exr"]
"""

OUTPUTS = ["box-pt.exr", "box-pt.png", "glossy-bdpt.exr", "glass-mmlt.exr"]


@pytest.fixture(scope="module", autouse=True)
def plexus_binary():
    if not (PLEXUS.is_file() and os.access(PLEXUS, os.X_OK)):
        pytest.fail(f"no plexus binary at {PLEXUS}: run `cargo build --release` (or set PLEXUS_BIN)")
    return PLEXUS


def make_batch(root: Path, jobs: str = BATCH) -> Path:
    """A batch directory: the three shipped Cornell boxes at RESOLUTION, a broken scene, the batch."""
    (root / "scenes").mkdir(parents=True)
    for name in ("cornell-box", "cornell-glossy", "cornell-glass"):
        text = (REPO / "scenes" / f"{name}.toml").read_text()
        small, n = re.subn(r"(?m)^resolution = \[\d+, \d+\]", f"resolution = {RESOLUTION}", text)
        assert n == 1, f"{name}.toml: no resolution line to shrink"
        (root / "scenes" / f"{name}.toml").write_text(small)
    # Valid TOML, invalid scene: plexus refuses it with exit 2 before any work.
    (root / "scenes" / "broken.toml").write_text(
        (root / "scenes" / "cornell-box.toml").read_text() + "\n[not_a_table_plexus_knows]\nx = 1\n"
    )
    batch = root / "batch.toml"
    batch.write_text(jobs)
    return batch


def exr_pixels(path: Path) -> tuple[dict[bytes, bytes], bytes]:
    """An OpenEXR file's header attributes (but the capture date, which differs per write) and the
    bytes after the header (offset table and pixel chunks)."""
    data = path.read_bytes()
    assert data[:4] == b"\x76\x2f\x31\x01", f"{path} is not an OpenEXR file"
    pos, attrs = 8, {}
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        size = int.from_bytes(data[type_end + 1 : type_end + 5], "little")
        value = data[type_end + 5 : type_end + 5 + size]
        attrs[data[pos:name_end]] = value
        pos = type_end + 5 + size
    attrs.pop(b"capDate", None)
    attrs.pop(b"utcOffset", None)
    return attrs, data[pos + 1 :]


def images(root: Path, names: list[str] = OUTPUTS) -> dict[str, object]:
    out = {}
    for name in names:
        p = root / "out" / name
        assert p.is_file(), f"{p} was not written"
        out[name] = exr_pixels(p) if name.endswith(".exr") else p.read_bytes()
    return out


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "plexus_batch", *args, "--plexus", str(PLEXUS)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The batch on one worker, through the command line."""
    root = tmp_path_factory.mktemp("one-worker")
    batch = make_batch(root)
    r = run_cli(str(batch), "--scheduler", "local", "--workers", "1")
    assert r.returncode == 0, r.stderr
    summary = json.loads((root / "batch.summary.json").read_text())
    assert summary["ok"] and summary["workers"] == 1
    # Shards are removed after their merge (keep_shards = false).
    assert not any((root / "shards").rglob("*.pxstate"))
    return images(root)


def test_two_workers_give_the_one_worker_images_bit_for_bit(reference, tmp_path):
    batch = make_batch(tmp_path)
    r = run_cli(str(batch), "--scheduler", "local", "--workers", "2")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "batch.summary.json").read_text())
    assert summary["workers"] == 2
    assert [(j["name"], j["ok"], j["shards_done"]) for j in summary["jobs"]] == [
        ("box-pt", True, 3),
        ("glossy-bdpt", True, 2),
        ("glass-mmlt", True, 2),
    ]
    # Progress streamed on stderr: one line per shard and per merge.
    assert r.stderr.count(" done in ") == 7 and r.stderr.count(" merged in ") == 3
    assert images(tmp_path) == reference
    # The merge wrote its JSON beside the first output.
    assert (tmp_path / "out" / "box-pt.json").is_file()


def test_a_killed_worker_s_shard_is_rerun_and_the_images_do_not_change(reference, tmp_path):
    batch = load(make_batch(tmp_path))
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0") as cluster, Client(cluster) as client:
        client.wait_for_workers(2)
        pids = client.run(os.getpid)
        result: dict = {}
        runner = threading.Thread(
            target=lambda: result.update(report=run_batch(batch, client, PLEXUS, progress=lambda _m: None))
        )
        runner.start()
        try:
            worker_pid, renders = _wait_for_a_running_shard(pids, timeout=120)
            os.kill(worker_pid, signal.SIGKILL)
            # The shard's plexus process dies with its worker (PR_SET_PDEATHSIG), so no orphan
            # writes the shard file that the rerun writes.
            _, alive = psutil.wait_procs(renders, timeout=30)
            assert not alive, f"plexus runs outlived their killed worker: {alive}"
        finally:
            runner.join(timeout=600)
    report = result["report"]
    assert report.ok, report.table()
    assert sum(j.shards_retried for j in report.jobs) >= 1, report.table()
    assert images(tmp_path) == reference


def test_a_broken_scene_fails_only_its_job_with_the_shard_s_error(reference, tmp_path):
    # The batch's first job (up to the second [[jobs]]) and the broken one.
    first_job = BATCH[: BATCH.index("[[jobs]]", BATCH.index("[[jobs]]") + 1)]
    batch = make_batch(tmp_path, first_job + BAD_JOB)
    # An existing scheduler, given by address, as on a cluster started by someone else.
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0") as cluster:
        r = run_cli(str(batch), "--scheduler", cluster.scheduler_address, "--summary", str(tmp_path / "s.json"))
    assert r.returncode == 1, r.stderr
    jobs = {j["name"]: j for j in json.loads((tmp_path / "s.json").read_text())["jobs"]}
    assert [n for n, j in jobs.items() if not j["ok"]] == ["broken"]
    error = jobs["broken"]["error"]
    # The shard's exit code and plexus's own one-line error, which names the scene file.
    assert re.match(r"shard [01]/2: exit 2: error: .*broken\.toml", error), error
    assert f"broken: {error}" in r.stdout
    assert not (tmp_path / "out" / "broken.exr").exists()
    box = ["box-pt.exr", "box-pt.png"]
    assert images(tmp_path, box) == {k: reference[k] for k in box}


def _wait_for_a_running_shard(pids: dict[str, int], timeout: float) -> tuple[int, list[psutil.Process]]:
    """A worker process with a `plexus render --shard` child running, and those children."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for pid in pids.values():
            renders = []
            for child in psutil.Process(pid).children(recursive=True):
                try:
                    cmd = child.cmdline()
                except psutil.Error:  # ended, or a zombie, between listing and reading
                    continue
                if cmd[:2] == [str(PLEXUS), "render"] and "--shard" in cmd:
                    renders.append(child)
            if renders:
                return pid, renders
        time.sleep(0.02)
    raise AssertionError(f"no shard was seen running within {timeout} s")
