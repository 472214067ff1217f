"""What runs on a Dask worker: one `plexus render --shard` or one `plexus merge`, as a subprocess.

A run that exits 2 (bad input: a broken scene, an unknown setting, mismatched shards) is returned as
a failed Outcome, not raised: it would fail the same way anywhere, so Dask must not retry it. Any
other failure (exit 1, killed by a signal, still running at the job's timeout) is raised as
PlexusFailed, which Dask retries up to the task's `retries`. A worker that dies is a different
thing: the scheduler reruns the task elsewhere by itself (up to
`distributed.scheduler.allowed-failures` deaths), and the plexus process dies with its worker
(PR_SET_PDEATHSIG below), so no orphan keeps writing the shard file the rerun writes.

Each run is the leader of its own process group (a new session), which a timeout or a cancelled
task kills as a whole with SIGKILL; being in its own session also keeps a terminal's Ctrl-C, which
plexus-batch handles, from reaching the renders of a local cluster.
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
    """A run-time failure (exit 1, a signal or the timeout) that another attempt may not repeat."""


class RunCancelled(RuntimeError):
    """The task was cancelled (by the client, or its worker is closing) while plexus ran: the run
    was killed and Dask discards this result."""


# How often a task waiting for its plexus run checks whether it was cancelled (seconds).
POLL_S = 0.25
# How long to wait for a run killed with SIGKILL to be reaped. A process blocked in the kernel (a
# hung network file system) dies only when the call returns, but it cannot run any more code of its
# own by then, so a retry that writes the same shard file is safe without waiting for it.
REAP_S = 10.0


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
    return _run(task.argv, task.label, task.timeout)


def run_merge(task: MergeTask, keep_shards: bool) -> Outcome:
    for out in task.outputs:
        out.parent.mkdir(parents=True, exist_ok=True)
    outcome = _run(task.argv, f"{task.job} merge", task.timeout)
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


def _run(argv: tuple[str, ...], label: str, timeout: float | None = None) -> Outcome:
    """Runs plexus; `timeout` (seconds, None for none) bounds the run's wall time."""
    start, t0 = time.time(), time.monotonic()
    proc = subprocess.Popen(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
        preexec_fn=_die_with_parent(),
    )
    stopped = None  # why the run was killed: "timeout" or "cancelled"
    stderr_bytes = b""
    while True:
        wait = POLL_S if timeout is None else min(POLL_S, max(0.0, t0 + timeout - time.monotonic()))
        try:
            # communicate() drains stderr while waiting, and a retry after its timeout loses nothing.
            stderr_bytes = proc.communicate(timeout=wait)[1]
            break
        except subprocess.TimeoutExpired:
            pass
        if timeout is not None and time.monotonic() - t0 >= timeout:
            stopped = "timeout"
        elif _cancelled():
            stopped = "cancelled"
        if stopped is not None:
            _kill_group(proc)
            try:
                stderr_bytes = proc.communicate(timeout=REAP_S)[1]
            except subprocess.TimeoutExpired:
                pass
            break
    seconds, end = time.monotonic() - t0, time.time()
    address = _address()
    if stopped == "cancelled":
        raise RunCancelled(f"{label} on {address}: cancelled; its processes were killed")
    if stopped == "timeout":
        raise PlexusFailed(
            f"{label} on {address} ({socket.gethostname()}): timed out after {timeout:g} s (the job's"
            " timeout) and was killed with its process group"
        )
    stderr = (stderr_bytes or b"").decode("utf-8", "replace")
    if proc.returncode == 0:
        return Outcome(True, 0, None, seconds, start, end, address)
    if proc.returncode == EXIT_BAD_INPUT:
        return Outcome(False, proc.returncode, error_line(stderr), seconds, start, end, address)
    if proc.returncode < 0:
        what = f"killed by {signal.Signals(-proc.returncode).name}"
    else:
        what = f"exit {proc.returncode}: {error_line(stderr)}"
    raise PlexusFailed(f"{label} on {address} ({socket.gethostname()}): {what}")


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL to the run's process group: plexus and anything it started. Only while the leader is
    not reaped (returncode None), so its pid, which is the group's id, cannot have been reused."""
    if proc.returncode is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:  # the whole group has exited since
            pass


def _cancelled() -> bool:
    """Whether the Dask task running this is cancelled: the client cancelled it (a failed job's other
    shards, an interrupted batch), it was released, or its worker is closing. Dask cannot stop a
    running task's thread; the task sees its state change on the worker and stops itself. Outside
    a Dask task, never."""
    worker = _worker()
    if worker is None:
        return False
    try:
        key = worker.get_current_task()
        ts = worker.state.tasks.get(key)
    except (AttributeError, KeyError):  # not in a task's thread, or another worker state layout
        return False
    return ts is None or ts.state in ("cancelled", "released", "forgotten")


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
    """A preexec_fn that makes the child receive SIGKILL when the thread that started it exits (where
    the platform can) and unblocks every signal: a local worker inherits plexus-batch's blocked
    SIGINT (cli.py), which plexus, with its own Ctrl-C handling, must not. libc is loaded before the
    fork: the child only calls into it."""
    parent = os.getpid()
    prctl = _libc.prctl if _libc is not None else None

    def preexec() -> None:
        signal.pthread_sigmask(signal.SIG_SETMASK, [])
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
            if os.getppid() != parent:  # the worker died between fork and prctl
                os._exit(1)

    return preexec

