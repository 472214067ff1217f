"""What runs on a Dask worker: one `plexus render --shard` or one `plexus merge`, as a subprocess.

A run that exits 2 (bad input: a broken scene, an unknown setting, mismatched shards) is returned as
a failed Outcome, not raised: it would fail the same way anywhere, so Dask must not retry it. Any
other failure (exit 1, killed by a signal) is raised as PlexusFailed, which Dask retries up to the
task's `retries`. A worker that dies is a different thing: the scheduler reruns the task elsewhere
by itself (up to `distributed.scheduler.allowed-failures` deaths), and the plexus process dies with
its worker (PR_SET_PDEATHSIG below), so no orphan keeps writing the shard file the rerun writes.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass

from .plan import MergeTask, ShardTask

# Worker events under this topic say "shard started" (with the batch run's id), so the client can
# count how many shards ran more than once: Dask reruns a task silently after its worker died.
EVENT_TOPIC = "plexus-batch"

# Exit code of `plexus` for bad input (README, "Errors and exit codes").
EXIT_BAD_INPUT = 2


@dataclass(frozen=True)
class Outcome:
    ok: bool
    exit_code: int
    error: str | None  # the run's one-line error (its last `error:` line on stderr), when not ok
    seconds: float  # wall time of the subprocess on the worker
    start: float  # time.time() at start and end, for the job's wall time across workers
    end: float
    worker: str


class PlexusFailed(RuntimeError):
    """A run-time failure (exit 1 or a signal) that another attempt may not repeat."""


def run_shard(task: ShardTask, run_id: str) -> Outcome:
    worker = _worker()
    if worker is not None:
        # Through the worker's client, a round trip: the event is on the scheduler before plexus
        # starts. (Worker.log_event batches it, and a worker killed within the batching interval,
        # which a loaded machine stretches, took it along: seen in the kill test.)
        from distributed import get_client

        msg = {"run": run_id, "job": task.job, "shard": task.index, "worker": worker.address}
        get_client().log_event(EVENT_TOPIC, msg)
    task.state.parent.mkdir(parents=True, exist_ok=True)
    return _run(task.argv, task.label)


def run_merge(task: MergeTask, keep_shards: bool) -> Outcome:
    for out in task.outputs:
        out.parent.mkdir(parents=True, exist_ok=True)
    outcome = _run(task.argv, f"{task.job} merge")
    if outcome.ok and not keep_shards:
        for p in task.shard_files:
            p.unlink(missing_ok=True)
        # The job's shard directory, when nothing else is left in it.
        try:
            task.shard_files[0].parent.rmdir()
        except (OSError, IndexError):
            pass
    return outcome


def error_line(stderr: str) -> str:
    """The line that says what went wrong: plexus's last `error: ...` line, else its last line."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    for line in reversed(lines):
        if line.startswith("error:"):
            return line
    return lines[-1] if lines else "(nothing on stderr)"


def _run(argv: tuple[str, ...], label: str) -> Outcome:
    start, t0 = time.time(), time.monotonic()
    proc = subprocess.run(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        preexec_fn=_die_with_parent(),
        check=False,
    )
    seconds, end = time.monotonic() - t0, time.time()
    stderr = proc.stderr.decode("utf-8", "replace")
    address = _address()
    if proc.returncode == 0:
        return Outcome(True, 0, None, seconds, start, end, address)
    if proc.returncode == EXIT_BAD_INPUT:
        return Outcome(False, proc.returncode, error_line(stderr), seconds, start, end, address)
    if proc.returncode < 0:
        what = f"killed by {signal.Signals(-proc.returncode).name}"
    else:
        what = f"exit {proc.returncode}: {error_line(stderr)}"
    raise PlexusFailed(f"{label} on {address} ({socket.gethostname()}): {what}")


def _worker():
    try:
        from distributed import get_worker

        return get_worker()
    except (ImportError, ValueError):  # not inside a Dask task
        return None


def _address() -> str:
    worker = _worker()
    return worker.address if worker is not None else f"local:{os.getpid()}"


# prctl(PR_SET_PDEATHSIG) is Linux's; elsewhere a killed worker's plexus run goes on until it ends.
_PR_SET_PDEATHSIG = 1
_libc = None
if sys.platform.startswith("linux"):
    try:
        _libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    except OSError:
        _libc = None


def _die_with_parent():
    """A preexec_fn that makes the child receive SIGKILL when the thread that started it exits, or
    None where that cannot be done. libc is loaded before the fork: the child only calls into it."""
    if _libc is None:
        return None
    parent = os.getpid()
    prctl = _libc.prctl

    def preexec() -> None:
        prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:  # the worker died between fork and prctl
            os._exit(1)

    return preexec

