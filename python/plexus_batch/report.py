"""What happened to a batch: per job, and the batch's own figures; the summary JSON and table.

Without Dask, so that the command line can name BatchInterrupted before it imports Dask.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field

from .batchfile import Batch


class BatchInterrupted(KeyboardInterrupt):
    """The batch was stopped by a signal; `report` (when the batch had started) says what completed."""

    def __init__(self, signal_name: str = "SIGINT", report: BatchReport | None = None):
        super().__init__(signal_name)
        self.signal_name = signal_name
        self.report = report


@dataclass
class JobReport:
    name: str
    ok: bool = False
    status: str = "pending"  # "ok", "failed" or "interrupted" once the batch has ended
    error: str | None = None
    outputs: list[str] = field(default_factory=list)
    shards: int = 0
    shards_done: int = 0
    shards_retried: int = 0  # shards that started more than once (worker died, or a failed run retried)
    wall_s: float | None = None  # first shard's start to the merge's end (worker clocks)
    worker_s: float = 0.0  # successful shard runs plus the merge, summed over workers
    merge_s: float | None = None


@dataclass
class BatchReport:
    batch: str
    workers: int
    wall_s: float = 0.0
    interrupted: str | None = None  # the signal that stopped the batch ("SIGINT", "SIGTERM")
    jobs: list[JobReport] = field(default_factory=list)

    @classmethod
    def not_started(cls, batch: Batch, workers: int, signal_name: str, wall_s: float) -> BatchReport:
        """The report of a batch interrupted before any task was submitted."""
        report = cls(batch=str(batch.path), workers=workers, wall_s=wall_s, interrupted=signal_name)
        report.jobs = [JobReport(name=j.name, shards=j.shards) for j in batch.jobs]
        report.mark_interrupted(signal_name)
        return report

    def mark_interrupted(self, signal_name: str) -> None:
        """Every job not ended (neither merged nor failed) becomes "interrupted"."""
        self.interrupted = signal_name
        for j in self.jobs:
            if j.status == "pending":
                j.status = "interrupted"
                j.error = f"interrupted by {signal_name} with {j.shards_done} of {j.shards} shards done"

    @property
    def ok(self) -> bool:
        return all(j.ok for j in self.jobs)

    def to_json(self) -> str:
        return json.dumps({**asdict(self), "ok": self.ok}, indent=2) + "\n"

    def table(self) -> str:
        rows = [("job", "status", "shards", "retried", "wall s", "worker s", "merge s")]
        for j in self.jobs:
            rows.append(
                (
                    j.name,
                    {"failed": "FAILED"}.get(j.status, j.status),
                    f"{j.shards_done}/{j.shards}",
                    str(j.shards_retried),
                    _secs(j.wall_s),
                    _secs(j.worker_s),
                    _secs(j.merge_s),
                )
            )
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        lines = ["  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))) for r in rows]
        lines += [f"{j.name}: {j.error}" for j in self.jobs if not j.ok]
        ok = sum(j.ok for j in self.jobs)
        stopped = f" (interrupted by {self.interrupted})" if self.interrupted else ""
        lines.append(f"{ok} of {len(self.jobs)} jobs ok in {self.wall_s:.2f} s on {self.workers} workers{stopped}")
        return "\n".join(lines)


def _secs(s: float | None) -> str:
    return "-" if s is None else f"{s:.2f}"


