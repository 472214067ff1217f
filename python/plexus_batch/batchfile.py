"""The batch file: a TOML list of render jobs, checked in full before anything is submitted.

```toml
shard_dir = "shards"            # optional; default "<batch-stem>.shards" beside the batch file
keep_shards = false             # optional; keep each job's shard files after its merge

[defaults]                      # optional; any job key but name, scene and outputs
integrator = "pt"
spp = 256
shards = 4

[[jobs]]
name = "box"                    # optional; default: the scene's file stem; unique in the batch
scene = "scenes/cornell-box.toml"
integrator = "bdpt"             # optional; default: the scene's [integrator]
spp = 1024                      # samples (MCMC: mutations) per pixel; required here or in defaults
seed = 7                        # optional; default 0
threads = 1                     # optional; threads of each shard's render; default 1
settings = { max_depth = 8 }    # optional; integrator settings, passed as --set key=value
outputs = ["out/box.exr", "out/box.png"]   # optional; default ["<name>.exr"]
shards = 8                      # optional; default 1
timeout = 600                   # optional; seconds one run (a shard or the merge) may take; 0: none
```

Relative paths are relative to the batch file's directory and are made absolute here, because the
workers that read the scenes and write the outputs run elsewhere (see docs/batch.md: every worker
must see the same paths).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


class BatchError(ValueError):
    """A batch file that cannot be run; the message is one line naming the file and the key."""


# The renderer's own limits (README: "Limits are checked before any work") are the renderer's to
# check; here only what the batch itself needs: positive counts that fit plexus's u64/u32 options.
MAX_SHARDS = 1 << 20
MAX_U64 = (1 << 64) - 1
# The timeout of a job that sets none: a shard is meant to be minutes of work (docs/batch.md, "How
# many shards"), and an hour bounds what a hung run holds a worker for.
DEFAULT_TIMEOUT_S = 3600.0
# A year: more is a typo, and larger values overflow the wait of threading primitives.
MAX_TIMEOUT_S = 365 * 24 * 3600.0

TOP_KEYS = ("shard_dir", "keep_shards", "defaults", "jobs")
JOB_KEYS = ("name", "scene", "integrator", "spp", "seed", "threads", "settings", "outputs", "shards", "timeout")
DEFAULT_KEYS = tuple(k for k in JOB_KEYS if k not in ("name", "scene", "outputs"))
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


@dataclass(frozen=True)
class Job:
    """One render of the batch, split into `shards` shards that `plexus merge` combines."""

    name: str
    scene: Path
    spp: int
    seed: int = 0
    threads: int = 1
    shards: int = 1
    integrator: str | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    outputs: tuple[Path, ...] = ()
    timeout: float | None = DEFAULT_TIMEOUT_S  # seconds per run of a shard or the merge; None: none


@dataclass(frozen=True)
class Batch:
    path: Path
    jobs: tuple[Job, ...]
    shard_dir: Path
    keep_shards: bool = False


def load(path: str | Path, default_timeout: float | None = DEFAULT_TIMEOUT_S) -> Batch:
    """Reads and checks a batch file; raises BatchError with one line on any problem.

    `default_timeout`: the timeout (seconds, None for none) of jobs that set none.
    """
    path = Path(path).absolute()
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise BatchError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from e
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise BatchError(f"{path}: not valid TOML: {e}") from e
    return parse(doc, path, default_timeout)


def parse(doc: dict[str, Any], path: Path, default_timeout: float | None = DEFAULT_TIMEOUT_S) -> Batch:
    """Checks a parsed batch document; `path` names the file in errors and anchors relative paths."""
    base = path.parent
    _check_keys(doc, TOP_KEYS, f"{path}")
    shard_dir = _path(doc.get("shard_dir", f"{path.stem}.shards"), base, f"{path}: shard_dir")
    keep = doc.get("keep_shards", False)
    if not isinstance(keep, bool):
        raise BatchError(f"{path}: keep_shards: expected true or false, got {_show(keep)}")

    defaults = doc.get("defaults", {})
    if not isinstance(defaults, dict):
        raise BatchError(f"{path}: defaults: expected a table, got {_show(defaults)}")
    _check_keys(defaults, DEFAULT_KEYS, f"{path}: [defaults]")

    raw_jobs = doc.get("jobs")
    if raw_jobs is None:
        raise BatchError(f"{path}: no jobs: add at least one [[jobs]] table with a scene")
    if not isinstance(raw_jobs, list) or not all(isinstance(j, dict) for j in raw_jobs):
        raise BatchError(f"{path}: jobs: expected [[jobs]] tables")
    if not raw_jobs:
        raise BatchError(f"{path}: no jobs: add at least one [[jobs]] table with a scene")

    jobs = []
    names: dict[str, int] = {}
    # Every file a job's merge writes (its outputs and their stats JSONs), by its real path (symbolic
    # links resolved), with the job and the output it comes from: two jobs writing one file would
    # lose one's image or record.
    written: dict[str, tuple[str, Path, Path]] = {}
    for i, raw in enumerate(raw_jobs):
        where = f"{path}: jobs[{i}]"
        job = _job(raw, defaults, base, where, default_timeout)
        if job.name in names:
            raise BatchError(f"{where}: name {job.name!r} is already the name of jobs[{names[job.name]}]")
        names[job.name] = i
        mine: dict[str, tuple[str, Path, Path]] = {}
        for out in job.outputs:
            for file in (out, stats_json_path(out)):
                key = os.path.realpath(file)
                if key in written:
                    raise BatchError(_clash(where, job.name, out, file, *written[key]))
                mine.setdefault(key, (job.name, out, file))
        written.update(mine)
        jobs.append(job)
    return Batch(path=path, jobs=tuple(jobs), shard_dir=shard_dir, keep_shards=keep)


def stats_json_path(image: Path) -> Path:
    """The stats JSON plexus writes beside an image: the image's path with `.json` for its extension
    (README, "The command line"), so `x.exr` and `x.png` share `x.json`."""
    return image.with_suffix(".json")


def _clash(where: str, job: str, out: Path, file: Path, other_job: str, other_out: Path, other_file: Path) -> str:
    """The one-line error for a file that job `job` (writing `file` for its output `out`) and an earlier
    job (writing `other_file` for `other_out`) both write."""
    if file == out and other_file == other_out:
        same = "" if out == other_out else f" (the same file as {other_out})"
        return f"{where}: output {out}{same} is also written by job {other_job!r}"
    if file != out and other_file != other_out:
        return (
            f"{where}: output {out} of job {job!r} and output {other_out} of job {other_job!r} share the"
            f" stats JSON {file}: each merge writes it, so one job's record would be lost"
        )
    if file == out:
        return f"{where}: output {out} of job {job!r} is the stats JSON of output {other_out} of job {other_job!r}"
    return f"{where}: the stats JSON {file} of output {out} of job {job!r} is an output of job {other_job!r}"


def _job(raw: dict[str, Any], defaults: dict[str, Any], base: Path, where: str, default_timeout: float | None) -> Job:
    _check_keys(raw, JOB_KEYS, where)
    merged = {**defaults, **raw}
    # Settings merge key by key, so a job can change one setting of the defaults'.
    settings = {}
    for source in (defaults, raw):
        s = source.get("settings", {})
        if not isinstance(s, dict):
            raise BatchError(f"{where}: settings: expected a table, got {_show(s)}")
        for k, v in s.items():
            if not isinstance(k, str) or not re.fullmatch(r"[A-Za-z0-9_]+", k):
                raise BatchError(f"{where}: settings: bad key {k!r} (expected letters, digits, _)")
            try:
                toml_value(v)
            except BatchError:
                raise BatchError(
                    f"{where}: settings.{k}: expected a number, string, boolean or array, got {_show(v)}"
                ) from None
            settings[k] = v

    if "scene" not in raw:
        raise BatchError(f"{where}: missing scene")
    scene = _path(raw["scene"], base, f"{where}: scene")
    name = raw.get("name", scene.stem)
    if not isinstance(name, str) or not NAME_RE.match(name):
        raise BatchError(
            f"{where}: name: expected letters, digits, '.', '_' or '-' (a file name), got {_show(name)}"
        )

    if "spp" not in merged:
        raise BatchError(f"{where}: missing spp (samples per pixel; shards take sample budgets only)")
    spp = _int(merged["spp"], f"{where}: spp", 1, MAX_U64)
    seed = _int(merged.get("seed", 0), f"{where}: seed", 0, MAX_U64)
    threads = _int(merged.get("threads", 1), f"{where}: threads", 1, 1024)
    shards = _int(merged.get("shards", 1), f"{where}: shards", 1, MAX_SHARDS)
    timeout = timeout_seconds(merged["timeout"], f"{where}: timeout") if "timeout" in merged else default_timeout
    integrator = merged.get("integrator")
    if integrator is not None and (not isinstance(integrator, str) or not integrator):
        raise BatchError(f"{where}: integrator: expected a name such as \"pt\", got {_show(integrator)}")

    raw_outputs = raw.get("outputs", [f"{name}.exr"])
    if isinstance(raw_outputs, str):
        raw_outputs = [raw_outputs]
    if not isinstance(raw_outputs, list) or not raw_outputs:
        raise BatchError(f"{where}: outputs: expected a non-empty list of image paths")
    outputs = tuple(_path(o, base, f"{where}: outputs") for o in raw_outputs)
    if len(set(outputs)) != len(outputs):
        raise BatchError(f"{where}: outputs: the same path twice")
    for o in outputs:
        if not o.suffix:
            raise BatchError(f"{where}: outputs: {o} has no extension (the format follows it)")

    return Job(
        name=name,
        scene=scene,
        spp=spp,
        seed=seed,
        threads=threads,
        shards=shards,
        integrator=integrator,
        settings=settings,
        outputs=outputs,
        timeout=timeout,
    )


def timeout_seconds(value: Any, where: str) -> float | None:
    """A timeout in seconds: a number from 0 to a year, where 0 means none (returned as None)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BatchError(f"{where}: expected seconds (a number; 0 for no timeout), got {_show(value)}")
    if not 0 <= value <= MAX_TIMEOUT_S:  # also refuses nan
        raise BatchError(f"{where}: {value} is out of range [0, {MAX_TIMEOUT_S:.0f}] (seconds; 0 for no timeout)")
    return float(value) if value > 0 else None


def _check_keys(table: dict[str, Any], allowed: tuple[str, ...], where: str) -> None:
    for k in table:
        if k not in allowed:
            raise BatchError(f"{where}: unknown key {k!r} (expected one of: {', '.join(allowed)})")


def _path(value: Any, base: Path, where: str) -> Path:
    if not isinstance(value, str) or not value:
        raise BatchError(f"{where}: expected a path string, got {_show(value)}")
    p = Path(value).expanduser()
    # normpath: "../../scenes/x.toml" reads better in commands and errors than base/../../...
    return Path(os.path.normpath(p if p.is_absolute() else base / p))


def _int(value: Any, where: str, lo: int, hi: int) -> int:
    # bool is an int in Python; `spp = true` is a mistake, not 1.
    if isinstance(value, bool) or not isinstance(value, int):
        raise BatchError(f"{where}: expected an integer, got {_show(value)}")
    if not lo <= value <= hi:
        raise BatchError(f"{where}: {value} is out of range [{lo}, {hi}]")
    return value


def _show(value: Any) -> str:
    return f"{type(value).__name__} {value!r}"


def toml_value(value: Any) -> str:
    """A TOML value as `plexus render --set key=VALUE` parses it (strings quoted, floats exact)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)  # shortest round-tripping form: the renderer reads the same double
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise BatchError(f"cannot pass {_show(value)} as an integrator setting")  # tables, dates


def _toml_string(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch in "\b\t\n\f\r":
            out.append({"\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)
