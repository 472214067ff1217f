"""The worker-side runs (plexus_batch.tasks) outside Dask, with small shell commands standing in for
the binary: which failures are final, which are retried, the error line, the clean-up after a
merge, and that the render dies with its worker."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest

from plexus_batch.plan import MergeTask, ShardTask
from plexus_batch.tasks import PlexusFailed, error_line, run_merge, run_shard


def sh(script: str) -> tuple[str, ...]:
    return ("/bin/sh", "-c", script)


def shard(tmp_path: Path, script: str) -> ShardTask:
    return ShardTask(job="j", index=1, count=3, argv=sh(script), state=tmp_path / "shards" / "j" / "s1.pxstate")


def test_success_and_its_timing(tmp_path):
    out = run_shard(shard(tmp_path, "sleep 0.2"), run_id="r")
    assert out.ok and out.exit_code == 0 and out.error is None
    assert out.seconds >= 0.2 and out.end - out.start >= 0.2
    assert (tmp_path / "shards" / "j").is_dir()  # made for the renderer, which only checks it


def test_bad_input_is_a_final_failure_with_plexus_s_error_line(tmp_path):
    out = run_shard(shard(tmp_path, "echo 'warning: x' >&2; echo 'error: s.toml: line 3: bad' >&2; echo more >&2; exit 2"), "r")
    assert not out.ok and out.exit_code == 2
    assert out.error == "error: s.toml: line 3: bad"


def test_run_time_failures_are_raised_so_that_dask_retries_them(tmp_path):
    with pytest.raises(PlexusFailed, match=r"j shard 1/3 on local:\d+ \(.*\): exit 1: error: disk full"):
        run_shard(shard(tmp_path, "echo 'error: disk full' >&2; exit 1"), "r")
    with pytest.raises(PlexusFailed, match="killed by SIGKILL"):
        run_shard(shard(tmp_path, "kill -9 $$"), "r")


def test_a_run_past_its_timeout_is_killed_with_its_children_and_raised_for_a_retry(tmp_path):
    """The whole process group goes: a `sleep` started by the run too (killing only the run's own
    process would leave it, holding the worker's stderr pipe open)."""
    pids = tmp_path / "pids"
    script = f"sleep 1000 & echo $$ $! > {pids}; wait"
    task = ShardTask("j", 1, 3, sh(script), tmp_path / "s1.pxstate", timeout=0.5)
    with pytest.raises(PlexusFailed, match=r"j shard 1/3 on local:\d+ \(.*\): timed out after 0.5 s"):
        run_shard(task, "r")
    procs = []
    for pid in map(int, pids.read_text().split()):
        try:
            procs.append(psutil.Process(pid))
        except psutil.NoSuchProcess:
            pass
    _, alive = psutil.wait_procs(procs, timeout=10)
    assert not [p for p in alive if p.status() != psutil.STATUS_ZOMBIE], alive
    # A run that ends within its timeout is not affected by it.
    assert run_shard(ShardTask("j", 1, 3, sh("true"), tmp_path / "s1.pxstate", timeout=30), "r").ok


def test_a_merge_past_its_timeout_is_killed_and_keeps_the_shard_files(tmp_path):
    shard_file = tmp_path / "s0.pxstate"
    shard_file.write_text("x")
    task = MergeTask(job="j", argv=sh("sleep 1000"), outputs=(tmp_path / "j.exr",), shard_files=(shard_file,), timeout=0.3)
    with pytest.raises(PlexusFailed, match=r"j merge on .*: timed out after 0.3 s"):
        run_merge(task, keep_shards=False)
    assert shard_file.exists()


def test_error_line():
    assert error_line("") == "(nothing on stderr)"
    assert error_line("thread panicked\n\n") == "thread panicked"
    assert error_line("error: a\nerror: b\nnote\n") == "error: b"


def test_merge_removes_the_shard_files_only_after_success(tmp_path):
    d = tmp_path / "shards" / "j"
    d.mkdir(parents=True)
    files = tuple(d / n for n in ("s0.pxstate", "s0.json", "s1.pxstate", "s1.json"))
    for f in files:
        f.write_text("x")
    out = tmp_path / "out" / "sub" / "j.exr"

    def merge(script: str) -> MergeTask:
        return MergeTask(job="j", argv=sh(script), outputs=(out,), shard_files=files)

    assert not run_merge(merge("echo 'error: overlapping units' >&2; exit 2"), keep_shards=False).ok
    assert all(f.exists() for f in files)
    assert out.parent.is_dir()  # output directories are made before the merge
    assert run_merge(merge("true"), keep_shards=True).ok
    assert all(f.exists() for f in files)
    assert run_merge(merge("true"), keep_shards=False).ok
    assert not any(f.exists() for f in files) and not d.exists()


def test_the_render_dies_with_the_process_that_started_it(tmp_path):
    """A worker killed with SIGKILL cannot stop its subprocess; PR_SET_PDEATHSIG does. Without it
    (tasks._run with preexec_fn=None) this test fails: the `sleep` was still running 10 s after its
    parent was killed."""
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).resolve().parents[1])!r})
        from plexus_batch.plan import ShardTask
        from plexus_batch.tasks import run_shard
        from pathlib import Path
        run_shard(ShardTask("j", 0, 1, ("sleep", "30"), Path({str(tmp_path / "s.pxstate")!r})), "r")
        """
    )
    parent = subprocess.Popen([sys.executable, "-c", script])
    try:
        deadline = time.monotonic() + 20
        children = []
        while not children and time.monotonic() < deadline:
            children = psutil.Process(parent.pid).children()
            time.sleep(0.02)
        assert children, "the render never started"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        _, alive = psutil.wait_procs(children, timeout=10)
        assert not alive
    finally:
        parent.kill()
