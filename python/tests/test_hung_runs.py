"""A plexus run that never ends, and a batch stopped by Ctrl-C or SIGTERM, with a fake `plexus` (a
shell script) so that each test takes seconds: the hung shard is killed at its job's timeout (with
its child processes) and retried, and the rest of the batch completes; an interrupted batch cancels
its work, kills the running renders, writes its summary and exits 130 (SIGINT) or 143 (SIGTERM)
without a traceback.

The fake renders shard K/N of a scene instantly, unless the scene file has the line `hang K/N`:
then it starts a `sleep` child and waits for it forever. Every run appends its pid (and the
sleep's) to `<scene>.log`, so a test can check that no process of a killed run is left.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest
from distributed import LocalCluster

FAKE_PLEXUS = r"""#!/bin/sh
verb=$1; shift
case $verb in
render)
    scene=$1; shift
    while [ $# -gt 0 ]; do
        case $1 in --shard) shard=$2; shift ;; --out) out=$2; shift ;; esac
        shift
    done
    echo "$$ $shard" >> "$scene.log"
    if grep -qx "hang $shard" "$scene"; then
        sleep 100000 &
        echo "$! $shard sleep" >> "$scene.log"
        wait
    fi
    echo "$shard" > "$out"
    echo '{}' > "${out%.*}.json"
    ;;
merge)
    while [ $# -gt 0 ]; do
        if [ "$1" = --out ]; then echo merged > "$2"; echo '{}' > "${2%.*}.json"; shift; fi
        shift
    done
    ;;
*)
    echo "error: fake plexus: unknown verb $verb" >&2
    exit 2
    ;;
esac
"""

# Job "stuck" hangs in its shard 1 of 2; job "fine" does not hang.
BATCH = """
shard_dir = "shards"

[[jobs]]
name = "fine"
scene = "fine.toml"
spp = 1
shards = 2
outputs = ["out/fine.exr", "out/fine.png"]

[[jobs]]
name = "stuck"
scene = "stuck.toml"
spp = 1
shards = 2
outputs = ["out/stuck.exr"]
"""

# A guard against this test hanging (as it did before the timeout existed), not a bound on speed.
HANG_GUARD_S = 300


def make_batch(root: Path, extra_stuck_keys: str = "") -> tuple[Path, Path]:
    fake = root / "plexus"
    fake.write_text(FAKE_PLEXUS)
    fake.chmod(0o755)
    (root / "fine.toml").write_text("# fake scene\n")
    (root / "stuck.toml").write_text("hang 1/2\n")
    batch = root / "batch.toml"
    batch.write_text(BATCH + extra_stuck_keys)
    return batch, fake


def logged_runs(root: Path, scene: str) -> list[tuple[int, str, bool]]:
    """(pid, shard, is the sleep child) of every run of the fake on `scene`."""
    log = root / f"{scene}.log"
    if not log.exists():
        return []
    runs = []
    for line in log.read_text().splitlines():
        pid, shard, *sleep = line.split()
        runs.append((int(pid), shard, bool(sleep)))
    return runs


def assert_all_ended(pids: list[int], timeout: float) -> None:
    procs = []
    for pid in pids:
        try:
            procs.append(psutil.Process(pid))
        except psutil.NoSuchProcess:
            pass
    _, alive = psutil.wait_procs(procs, timeout=timeout)
    alive = [p for p in alive if p.status() != psutil.STATUS_ZOMBIE]
    assert not alive, f"processes of a killed run are still running: {alive}"


def start_cli(root: Path, batch: Path, fake: Path, *args: str) -> subprocess.Popen:
    """plexus-batch in its own process group, with SIGINT's default action restored (a shell runs a
    background command with SIGINT ignored, and the command keeps that), as a terminal starts it;
    its stdout and stderr go to `root`/stdout and `root`/stderr."""
    with open(root / "stdout", "w") as out, open(root / "stderr", "w") as err:
        return subprocess.Popen(
            [sys.executable, "-m", "plexus_batch", str(batch), "--plexus", str(fake), *args],
            stdout=out,
            stderr=err,
            start_new_session=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )


def wait_until_stuck(root: Path, cli: subprocess.Popen) -> None:
    """Until plexus-batch has reported job "fine" merged and the hung shard of job "stuck" runs."""
    deadline = time.monotonic() + HANG_GUARD_S
    while time.monotonic() < deadline:
        sleeping = any(sleep for _, _, sleep in logged_runs(root, "stuck.toml"))
        if sleeping and "fine: merged in" in (root / "stderr").read_text():
            return
        if cli.poll() is not None:
            pytest.fail(f"plexus-batch ended early with {cli.returncode}:\n{ended(root, cli)[1]}")
        time.sleep(0.05)
    pytest.fail("the batch never reached its hung shard")


def ended(root: Path, cli: subprocess.Popen) -> tuple[str, str]:
    """plexus-batch's stdout and stderr once it has exited."""
    cli.wait(timeout=HANG_GUARD_S)
    return (root / "stdout").read_text(), (root / "stderr").read_text()


def test_a_hung_shard_is_killed_at_its_timeout_retried_and_fails_only_its_job(tmp_path):
    batch, fake = make_batch(tmp_path, "timeout = 2\n")
    r = subprocess.run(
        [sys.executable, "-m", "plexus_batch", str(batch), "--plexus", str(fake), "--workers", "2", "--retries", "1"],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
        check=False,
    )
    assert r.returncode == 1, r.stderr
    summary = json.loads((tmp_path / "batch.summary.json").read_text())
    jobs = {j["name"]: j for j in summary["jobs"]}
    assert jobs["fine"]["ok"] and jobs["fine"]["status"] == "ok"
    assert (tmp_path / "out" / "fine.exr").is_file() and (tmp_path / "out" / "fine.png").is_file()
    stuck = jobs["stuck"]
    assert not stuck["ok"] and stuck["status"] == "failed"
    assert re.match(r"shard 1/2: PlexusFailed: stuck shard 1/2 on .*: timed out after 2 s", stuck["error"]), stuck
    assert f"stuck: {stuck['error']}" in r.stdout
    # Shard 1 ran twice (the retry), each time killed with its `sleep` child: nothing is left.
    runs = logged_runs(tmp_path, "stuck.toml")
    assert sorted((shard, sleep) for _, shard, sleep in runs) == [
        ("0/2", False), ("1/2", False), ("1/2", False), ("1/2", True), ("1/2", True),
    ]  # fmt: skip
    assert stuck["shards_retried"] == 1
    assert_all_ended([pid for pid, _, _ in runs], timeout=10)


def test_ctrl_c_on_a_local_cluster_writes_the_summary_and_exits_130(tmp_path):
    batch, fake = make_batch(tmp_path)
    cli = start_cli(tmp_path, batch, fake, "--workers", "2")
    try:
        wait_until_stuck(tmp_path, cli)
        # A terminal's Ctrl-C: SIGINT to the whole foreground process group, Dask's local workers
        # included.
        os.killpg(cli.pid, signal.SIGINT)
        out, err = ended(tmp_path, cli)
    finally:
        if cli.poll() is None:
            os.killpg(cli.pid, signal.SIGKILL)
    assert cli.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    summary = json.loads((tmp_path / "batch.summary.json").read_text())
    assert summary["interrupted"] == "SIGINT" and not summary["ok"]
    jobs = {j["name"]: j for j in summary["jobs"]}
    assert (jobs["fine"]["status"], jobs["fine"]["shards_done"]) == ("ok", 2)
    stuck = jobs["stuck"]
    assert (stuck["status"], stuck["ok"], stuck["shards_done"]) == ("interrupted", False, 1)
    assert stuck["error"] == "interrupted by SIGINT with 1 of 2 shards done", stuck
    assert "interrupted by SIGINT" in err and str(tmp_path / "batch.summary.json") in err
    assert "stuck" in out and "interrupted" in out  # the table
    assert_all_ended([pid for pid, _, _ in logged_runs(tmp_path, "stuck.toml")], timeout=30)


def test_sigterm_on_a_running_scheduler_cancels_the_running_shard_and_exits_143(tmp_path):
    batch, fake = make_batch(tmp_path)
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0") as cluster:
        cli = start_cli(tmp_path, batch, fake, "--scheduler", cluster.scheduler_address)
        try:
            wait_until_stuck(tmp_path, cli)
            cli.send_signal(signal.SIGTERM)
            out, err = ended(tmp_path, cli)
        finally:
            if cli.poll() is None:
                os.killpg(cli.pid, signal.SIGKILL)
        # The workers outlive plexus-batch here: the hung render must be stopped by the
        # cancellation, not by its worker's exit.
        assert_all_ended([pid for pid, _, _ in logged_runs(tmp_path, "stuck.toml")], timeout=30)
    assert cli.returncode == 143, err
    assert "Traceback" not in err, err
    summary = json.loads((tmp_path / "batch.summary.json").read_text())
    assert summary["interrupted"] == "SIGTERM"
    assert [(j["name"], j["status"]) for j in summary["jobs"]] == [("fine", "ok"), ("stuck", "interrupted")]
