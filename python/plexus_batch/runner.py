"""The client side: submit every shard, stream progress, merge each job once its shards are done.

Every shard is one Dask task; a job's merge is one more task, submitted when the job's last shard
has finished (so merges run while other jobs still render). Earlier jobs get higher priority, so
jobs finish, and merge, roughly in batch order rather than all at the end. A job whose shard fails
is marked failed with that shard's error and its other tasks are cancelled; the other jobs go on.

An interrupt (KeyboardInterrupt, or the CLI's BatchInterrupted for SIGTERM) while the batch runs
cancels every task not done, a running one included (tasks.py: the task kills its plexus run), and
is raised again as BatchInterrupted carrying the report of what completed and what did not.
"""

from __future__ import annotations

import sys
import time
import uuid
from collections import Counter
from pathlib import Path
from typing import Callable

from distributed import Client, as_completed

from .batchfile import Batch
from .plan import plan
from .report import BatchInterrupted, BatchReport, JobReport
from .tasks import EVENT_TOPIC, Outcome, run_merge, run_shard

__all__ = ["BatchInterrupted", "BatchReport", "JobReport", "run_batch", "stderr_progress"]


def stderr_progress(start: float) -> Callable[[str], None]:
    def progress(message: str) -> None:
        print(f"[{time.monotonic() - start:7.1f}s] {message}", file=sys.stderr, flush=True)

    return progress


def run_batch(
    batch: Batch,
    client: Client,
    plexus: Path | str,
    *,
    retries: int = 1,
    progress: Callable[[str], None] | None = None,
) -> BatchReport:
    """Runs every job of `batch` on `client`'s cluster and returns what happened to each.

    `retries`: further attempts of a shard or merge whose plexus run failed at run time (exit 1, a
    signal, or the job's timeout); a worker's death is retried by the scheduler itself, bad input
    (exit 2) never. An interrupt cancels what is not done and raises BatchInterrupted with the
    report.
    """
    t0 = time.monotonic()
    progress = progress or stderr_progress(t0)
    run_id = uuid.uuid4().hex[:12]
    plans = plan(batch, str(plexus))
    workers = len(client.nthreads())
    report = BatchReport(batch=str(batch.path), workers=workers)
    reports = {p.job.name: JobReport(name=p.job.name, shards=p.job.shards) for p in plans}
    report.jobs = list(reports.values())
    by_name = {p.job.name: p for p in plans}

    # future key -> (job name, shard index or None for the merge)
    what: dict[str, tuple[str, int | None]] = {}
    futures: dict[str, list] = {name: [] for name in by_name}
    outcomes: dict[str, list[Outcome]] = {name: [] for name in by_name}
    total_tasks = sum(p.job.shards + 1 for p in plans)
    finished_tasks = 0

    def fail(name: str, message: str) -> None:
        r = reports[name]
        if r.error is None:
            r.error = message
            r.status = "failed"
            progress(f"{name}: FAILED: {message}")
            client.cancel([f for f in futures[name] if not f.done()])

    interrupted = None
    try:
        ac = as_completed()
        for rank, p in enumerate(plans):
            priority = len(plans) - rank
            for s in p.shards:
                f = client.submit(
                    run_shard,
                    s,
                    run_id,
                    key=f"plexus-shard-{p.job.name}-{s.index}-{run_id}",
                    pure=False,
                    retries=retries,
                    priority=priority,
                )
                what[f.key] = (p.job.name, s.index)
                futures[p.job.name].append(f)
                ac.add(f)
        progress(f"submitted {sum(p.job.shards for p in plans)} shards of {len(plans)} jobs to {workers} workers")

        for f in ac:
            name, index = what[f.key]
            r = reports[name]
            finished_tasks += 1
            if r.error is not None or f.status == "cancelled":
                continue
            label = f"shard {index}/{r.shards}" if index is not None else "merge"
            if f.status == "error":
                fail(name, f"{label}: {_exception_line(f.exception())}")
                continue
            outcome: Outcome = f.result()
            if not outcome.ok:
                fail(name, f"{label}: exit {outcome.exit_code}: {outcome.error}")
                continue
            outcomes[name].append(outcome)
            if index is not None:
                r.shards_done += 1
                progress(
                    f"{name}: {label} done in {outcome.seconds:.2f} s on {outcome.worker}"
                    f" ({r.shards_done}/{r.shards} shards; {finished_tasks}/{total_tasks} tasks)"
                )
                if r.shards_done == r.shards:
                    p = by_name[name]
                    mf = client.submit(
                        run_merge,
                        p.merge,
                        batch.keep_shards,
                        key=f"plexus-merge-{name}-{run_id}",
                        pure=False,
                        retries=retries,
                        priority=len(plans) + 1,
                    )
                    what[mf.key] = (name, None)
                    futures[name].append(mf)
                    ac.add(mf)
            else:
                r.ok = True
                r.status = "ok"
                r.merge_s = outcome.seconds
                r.outputs = [str(o) for o in by_name[name].merge.outputs]
                progress(f"{name}: merged in {outcome.seconds:.2f} s -> {', '.join(r.outputs)}")
    except KeyboardInterrupt as e:
        interrupted = getattr(e, "signal_name", "SIGINT")
        progress(f"interrupted by {interrupted}: cancelling every task not done")
        # Running tasks included: each kills its plexus run when it sees itself cancelled.
        client.cancel([f for fs in futures.values() for f in fs if not f.done()])
        report.mark_interrupted(interrupted)

    for name, r in reports.items():
        done = outcomes[name]
        r.worker_s = sum(o.seconds for o in done)
        if r.ok:
            r.wall_s = max(o.end for o in done) - min(o.start for o in done)
    for name, n in _starts(client, run_id).items():
        if name in reports:
            reports[name].shards_retried = n
    report.wall_s = time.monotonic() - t0
    if interrupted is not None:
        raise BatchInterrupted(interrupted, report)
    return report


def _starts(client: Client, run_id: str) -> dict[str, int]:
    """Per job, how many of its shards the workers started more than once in this run."""
    starts = Counter()
    for _, msg in client.get_events(EVENT_TOPIC):
        if isinstance(msg, dict) and msg.get("run") == run_id:
            starts[(msg["job"], msg["shard"])] += 1
    retried: Counter = Counter()
    for (job, _), n in starts.items():
        if n > 1:
            retried[job] += 1
    return dict(retried)


def _exception_line(e: BaseException | None) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0] if text else ''}".rstrip(": ")

