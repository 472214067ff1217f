"""`plexus-batch BATCH.toml [--scheduler local|ADDRESS] ...`: run a batch file on a Dask cluster.

Exit codes, as plexus's own: 0 every job ok; 1 the batch ran but a job failed (the summary says
which and why); 2 bad input (the batch file, the arguments, no plexus binary), one `error:` line;
128 + the signal's number when SIGINT (130) or SIGTERM (143) stopped it, after writing the summary.
"""

from __future__ import annotations

import argparse
import os
import shlex
import signal
import sys
import time
from pathlib import Path

from . import __version__
from .batchfile import DEFAULT_TIMEOUT_S, BatchError, load, timeout_seconds
from .plan import find_plexus, plan
from .report import BatchInterrupted, BatchReport


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(
        prog="plexus-batch",
        description="Render a batch of plexus jobs on Dask: one task per shard, merged per job.",
    )
    ap.add_argument("batch", type=Path, help="batch file (TOML; see docs/batch.md)")
    where = ap.add_mutually_exclusive_group()
    where.add_argument(
        "--scheduler",
        default="local",
        metavar="local|ADDRESS",
        help="'local' (default) starts a LocalCluster here; an address (tcp://host:8786) uses a running scheduler",
    )
    where.add_argument("--scheduler-file", type=Path, metavar="PATH", help="a running scheduler's JSON file")
    ap.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="with --scheduler local: worker processes of one thread each (default: the cores here)",
    )
    ap.add_argument("--plexus", metavar="PATH", help="the plexus binary (default: plexus on the PATH, else target/release/plexus)")
    ap.add_argument("--summary", type=Path, metavar="PATH", help="summary JSON (default: <batch-stem>.summary.json beside the batch file)")
    ap.add_argument("--retries", type=int, default=1, metavar="R", help="attempts after a run-time failure (exit 1, a signal or the timeout; default 1)")
    ap.add_argument(
        "--timeout",
        type=float,
        metavar="SECONDS",
        help=f"seconds one plexus run (a shard or a merge) may take, for jobs whose batch file sets no timeout;"
        f" 0: none (default {DEFAULT_TIMEOUT_S:g})",
    )
    ap.add_argument("--dashboard", metavar="ADDRESS", help="with --scheduler local: serve Dask's dashboard here, e.g. :8787 (needs bokeh)")
    ap.add_argument("--dry-run", action="store_true", help="print the plexus commands and exit")
    ap.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    ap.add_argument("--version", action="version", version=f"plexus-batch {__version__}")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except KeyboardInterrupt:  # before the batch was read: nothing to cancel or summarise
        print("error: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT


def _main(argv: list[str] | None) -> int:
    args = parse_args(argv)
    try:
        default_timeout = DEFAULT_TIMEOUT_S if args.timeout is None else timeout_seconds(args.timeout, "--timeout")
        batch = load(args.batch, default_timeout)
        if args.workers is not None and not 1 <= args.workers <= 4096:
            raise BatchError(f"--workers {args.workers}: expected 1 to 4096")
        if args.workers is not None and args.scheduler != "local":
            raise BatchError("--workers applies to --scheduler local only (a running cluster has its own)")
        if args.retries < 0:
            raise BatchError(f"--retries {args.retries}: expected 0 or more")
        plexus = find_plexus(args.plexus)
    except (BatchError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2

    if args.dry_run:
        for p in plan(batch, str(plexus)):
            for s in p.shards:
                print(shlex.join(s.argv))
            print(shlex.join(p.merge.argv))
        return 0

    summary = args.summary or batch.path.with_name(f"{batch.path.stem}.summary.json")

    signals = _Signals()

    def write_summary(report: BatchReport) -> None:
        signals.summary_written = True  # from here on, a signal cannot lose or change the summary
        summary.parent.mkdir(parents=True, exist_ok=True)
        summary.write_text(report.to_json(), encoding="utf-8")
        print(report.table(), flush=True)
        print(f"summary: {summary}", flush=True)

    signals.install()
    t0 = time.monotonic()
    try:
        report = _run(batch, args, plexus, write_summary)
    except BatchInterrupted as e:
        if e.report is None:  # interrupted while the cluster started: no task was submitted
            write_summary(BatchReport.not_started(batch, 0, e.signal_name, time.monotonic() - t0))
        done = sum(j.ok for j in e.report.jobs) if e.report is not None else 0
        print(
            f"error: interrupted by {e.signal_name}: {done} of {len(batch.jobs)} jobs done, the others cancelled"
            f" (their shard files are left in place); summary: {summary}",
            file=sys.stderr,
        )
        return 128 + signal.Signals[e.signal_name].value
    finally:
        signals.restore()
    return 0 if report.ok else 1


class _Signals:
    """SIGINT and SIGTERM stop the batch: the first one raises BatchInterrupted in the main thread
    (run_batch cancels the tasks and reports). Later ones, and any once the summary is written, are
    ignored while the cluster stops, which takes seconds. A signal ignored when plexus-batch
    started (a shell runs a background command with SIGINT ignored) stays ignored."""

    def __init__(self) -> None:
        self.received: str | None = None
        self.summary_written = False
        self._previous: dict[int, object] = {}

    def install(self) -> None:
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous = signal.getsignal(sig)
            if previous is not signal.SIG_IGN:
                self._previous[sig] = previous
                signal.signal(sig, self._handle)

    def restore(self) -> None:
        for sig, previous in self._previous.items():
            signal.signal(sig, previous)

    def _handle(self, signum: int, _frame) -> None:
        if self.received is None and not self.summary_written:
            self.received = signal.Signals(signum).name
            raise BatchInterrupted(self.received)


def _run(batch, args: argparse.Namespace, plexus: Path, write_summary) -> BatchReport:
    """Runs the batch on the cluster the arguments name and writes its summary before the cluster
    closes (closing takes seconds; the summary is what an interrupt must not lose)."""
    # Imported here so that `--help`, `--dry-run` and batch-file errors do not pay for Dask's import.
    from distributed import Client, LocalCluster

    from .runner import run_batch

    def run(client: Client, dashboard: bool):
        if dashboard and not args.quiet:
            print(f"dashboard: {client.dashboard_link}", file=sys.stderr)
        progress = (lambda _msg: None) if args.quiet else None
        try:
            report = run_batch(batch, client, plexus, retries=args.retries, progress=progress)
        except BatchInterrupted as e:
            write_summary(e.report)
            raise
        write_summary(report)
        return report

    if args.scheduler_file is not None:
        with Client(scheduler_file=str(args.scheduler_file)) as client:
            return run(client, True)
    if args.scheduler != "local":
        with Client(args.scheduler) as client:
            return run(client, True)
    workers = args.workers or os.cpu_count() or 1
    # A terminal's Ctrl-C is sent to the whole foreground process group, local workers included,
    # which would die of it with tracebacks: plexus-batch alone handles it. The workers ignore SIGINT
    # (local_worker.py), and start with it ignored: it is ignored here while the cluster starts
    # them, so a Ctrl-C in those seconds is lost.
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        # One thread per worker: a shard's render has its own threads (the job's `threads`), and one
        # task per worker at a time keeps a worker's death to one shard.
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            # Without --dashboard, the scheduler's HTTP server (dashboard or not) takes a free port,
            # so that two local batches do not contend for 8787.
            dashboard_address=args.dashboard or ":0",
            preload=["plexus_batch.local_worker"],
        )
    finally:
        signal.signal(signal.SIGINT, handler)
    with cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        return run(client, args.dashboard is not None)
