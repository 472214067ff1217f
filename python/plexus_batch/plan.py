"""From a checked batch to the exact `plexus` command lines: one render per shard, one merge per job.

The commands follow the state-file contract (TEAM.md, "State files"):
`plexus render SCENE [--integrator I] --spp N --seed S --threads T [--set k=v]... --shard K/N
--out SHARD.pxstate` and `plexus merge SHARD.pxstate... --out IMAGE...`. Planning is pure (no
Dask, no binary), so it is unit-tested on its own.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from .batchfile import Batch, Job, toml_value


@dataclass(frozen=True)
class ShardTask:
    job: str
    index: int
    count: int
    argv: tuple[str, ...]
    state: Path  # SHARD.pxstate; the renderer writes SHARD.json beside it
    timeout: float | None = None  # seconds one run may take before it is killed; None: no limit

    @property
    def label(self) -> str:
        return f"{self.job} shard {self.index}/{self.count}"


@dataclass(frozen=True)
class MergeTask:
    job: str
    argv: tuple[str, ...]
    outputs: tuple[Path, ...]
    shard_files: tuple[Path, ...]  # removed after a successful merge unless keep_shards
    timeout: float | None = None


@dataclass(frozen=True)
class JobPlan:
    job: Job
    shards: tuple[ShardTask, ...]
    merge: MergeTask


def shard_state_path(batch: Batch, job: Job, index: int) -> Path:
    """`<shard_dir>/<job>/shard-KKK-of-NNN.pxstate`, zero-padded so the files list in order."""
    width = len(str(job.shards - 1))
    return batch.shard_dir / job.name / f"shard-{index:0{width}d}-of-{job.shards}.pxstate"


def render_argv(plexus: str, job: Job, index: int, state: Path) -> tuple[str, ...]:
    argv = [plexus, "render", str(job.scene)]
    if job.integrator is not None:
        argv += ["--integrator", job.integrator]
    argv += ["--spp", str(job.spp), "--seed", str(job.seed), "--threads", str(job.threads)]
    for key, value in job.settings.items():
        argv += ["--set", f"{key}={toml_value(value)}"]
    argv += ["--shard", f"{index}/{job.shards}", "--out", str(state)]
    return tuple(argv)


def merge_argv(plexus: str, states: list[Path], outputs: tuple[Path, ...]) -> tuple[str, ...]:
    argv = [plexus, "merge", *map(str, states)]
    for out in outputs:
        argv += ["--out", str(out)]
    return tuple(argv)


def plan(batch: Batch, plexus: str) -> list[JobPlan]:
    plans = []
    for job in batch.jobs:
        shards = []
        for k in range(job.shards):
            state = shard_state_path(batch, job, k)
            shards.append(
                ShardTask(
                    job=job.name,
                    index=k,
                    count=job.shards,
                    argv=render_argv(plexus, job, k, state),
                    state=state,
                    timeout=job.timeout,
                )
            )
        states = [s.state for s in shards]
        leftovers = tuple(p for s in states for p in (s, s.with_suffix(".json")))
        merge = MergeTask(
            job=job.name,
            argv=merge_argv(plexus, states, job.outputs),
            outputs=job.outputs,
            shard_files=leftovers,
            timeout=job.timeout,
        )
        plans.append(JobPlan(job=job, shards=tuple(shards), merge=merge))
    return plans


def find_plexus(explicit: str | None, cwd: Path | None = None) -> Path:
    """The `plexus` binary the workers run: `--plexus PATH`, else `plexus` on the PATH, else
    `target/release/plexus` under the current directory or the checkout this package is in.

    Resolved once, here, to an absolute path: every worker runs that same path, which (like the
    scenes) must exist on every worker's machine. Raises FileNotFoundError naming what was tried.
    """
    cwd = cwd or Path.cwd()
    if explicit is not None:
        p = Path(explicit).expanduser()
        p = p if p.is_absolute() else cwd / p
        if not (p.is_file() and os.access(p, os.X_OK)):
            raise FileNotFoundError(f"--plexus {explicit}: not an executable file")
        return p
    tried = []
    on_path = shutil.which("plexus")
    if on_path:
        return Path(on_path).absolute()
    tried.append("plexus on the PATH")
    checkout = Path(__file__).resolve().parent.parent.parent
    for root in dict.fromkeys((cwd, checkout)):
        p = root / "target" / "release" / "plexus"
        if p.is_file() and os.access(p, os.X_OK):
            return p
        tried.append(str(p))
    raise FileNotFoundError(f"no plexus binary (tried {', '.join(tried)}); build it or pass --plexus PATH")
