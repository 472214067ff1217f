"""`plexus-batch BATCH.toml [--scheduler local|ADDRESS] ...`: run a batch file on a Dask cluster.

Exit codes, as plexus's own: 0 every job ok; 1 the batch ran but a job failed (the summary says
which and why); 2 bad input (the batch file, the arguments, no plexus binary), one `error:` line.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from . import __version__
from .batchfile import BatchError, load
from .plan import find_plexus, plan


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
    ap.add_argument("--retries", type=int, default=1, metavar="R", help="attempts after a run-time failure (exit 1 or a signal; default 1)")
    ap.add_argument("--dashboard", metavar="ADDRESS", help="with --scheduler local: serve Dask's dashboard here, e.g. :8787 (needs bokeh)")
    ap.add_argument("--dry-run", action="store_true", help="print the plexus commands and exit")
    ap.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    ap.add_argument("--version", action="version", version=f"plexus-batch {__version__}")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        batch = load(args.batch)
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
    try:
        report = _run(batch, args, plexus)
    except KeyboardInterrupt:
        print("error: interrupted; shard files are left in place", file=sys.stderr)
        return 130
    summary.parent.mkdir(parents=True, exist_ok=True)
    summary.write_text(report.to_json(), encoding="utf-8")
    print(report.table())
    print(f"summary: {summary}")
    return 0 if report.ok else 1


def _run(batch, args: argparse.Namespace, plexus: Path):
    # Imported here so that `--help`, `--dry-run` and batch-file errors do not pay for Dask's import.
    from distributed import Client, LocalCluster

    from .runner import run_batch

    def run(client: Client, dashboard: bool):
        if dashboard and not args.quiet:
            print(f"dashboard: {client.dashboard_link}", file=sys.stderr)
        progress = (lambda _msg: None) if args.quiet else None
        return run_batch(batch, client, plexus, retries=args.retries, progress=progress)

    if args.scheduler_file is not None:
        with Client(scheduler_file=str(args.scheduler_file)) as client:
            return run(client, True)
    if args.scheduler != "local":
        with Client(args.scheduler) as client:
            return run(client, True)
    workers = args.workers or os.cpu_count() or 1
    # One thread per worker: a shard's render has its own threads (the job's `threads`), and one
    # task per worker at a time keeps a worker's death to one shard.
    with LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        # Without --dashboard, the scheduler's HTTP server (dashboard or not) takes a free port, so
        # that two local batches do not contend for 8787.
        dashboard_address=args.dashboard or ":0",
    ) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        return run(client, args.dashboard is not None)
