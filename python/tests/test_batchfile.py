"""Batch-file parsing and planning, without Dask or the plexus binary."""

from __future__ import annotations

import shlex
import tomllib
from pathlib import Path

import pytest

from plexus_batch.batchfile import DEFAULT_TIMEOUT_S, BatchError, load, parse, toml_value
from plexus_batch.plan import find_plexus, plan, shard_state_path

BATCH = """
shard_dir = "work/shards"

[defaults]
integrator = "pt"
spp = 64
shards = 3
settings = { max_depth = 8, mis = "balance" }

[[jobs]]
scene = "scenes/box.toml"
outputs = ["out/box.exr", "out/box.png"]

[[jobs]]
name = "glossy-bdpt"
scene = "/abs/glossy.toml"
integrator = "bdpt"
spp = 128
seed = 7
threads = 2
shards = 12
settings = { max_depth = 5, rr = 0.25, lights = [1, 2] }
"""


def batch(text: str = BATCH, path: Path = Path("/data/b/batch.toml")):
    return parse(tomllib.loads(text), path)


def test_defaults_and_overrides():
    b = batch()
    box, glossy = b.jobs
    assert b.shard_dir == Path("/data/b/work/shards") and b.keep_shards is False
    assert box.name == "box" and box.scene == Path("/data/b/scenes/box.toml")
    assert (box.integrator, box.spp, box.seed, box.threads, box.shards) == ("pt", 64, 0, 1, 3)
    assert box.settings == {"max_depth": 8, "mis": "balance"}
    assert box.outputs == (Path("/data/b/out/box.exr"), Path("/data/b/out/box.png"))
    # A job's settings replace the defaults' key by key, not as a whole table.
    assert glossy.settings == {"max_depth": 5, "mis": "balance", "rr": 0.25, "lights": [1, 2]}
    assert (glossy.integrator, glossy.spp, glossy.seed, glossy.threads, glossy.shards) == ("bdpt", 128, 7, 2, 12)
    assert glossy.scene == Path("/abs/glossy.toml")
    assert glossy.outputs == (Path("/data/b/glossy-bdpt.exr"),)


def test_plan_commands_follow_the_state_file_contract():
    b = batch()
    plans = plan(b, "/opt/plexus")
    box, glossy = plans
    assert [s.index for s in box.shards] == [0, 1, 2]
    assert box.shards[1].argv == (
        "/opt/plexus", "render", "/data/b/scenes/box.toml", "--integrator", "pt", "--spp", "64",
        "--seed", "0", "--threads", "1", "--set", "max_depth=8", "--set", 'mis="balance"',
        "--shard", "1/3", "--out", "/data/b/work/shards/box/shard-1-of-3.pxstate",
    )  # fmt: skip
    assert box.merge.argv == (
        "/opt/plexus", "merge",
        "/data/b/work/shards/box/shard-0-of-3.pxstate",
        "/data/b/work/shards/box/shard-1-of-3.pxstate",
        "/data/b/work/shards/box/shard-2-of-3.pxstate",
        "--out", "/data/b/out/box.exr", "--out", "/data/b/out/box.png",
    )  # fmt: skip
    # Every shard's state file and its JSON are what the merge leaves to clean up.
    assert len(box.merge.shard_files) == 6
    assert Path("/data/b/work/shards/box/shard-2-of-3.json") in box.merge.shard_files
    # Zero-padded indices: shard files list in shard order.
    assert glossy.shards[3].state.name == "shard-03-of-12.pxstate"
    assert "--shard" in glossy.shards[11].argv and "11/12" in glossy.shards[11].argv
    # Settings in order: the defaults' keys (with the job's values), then the job's own.
    assert glossy.shards[0].argv[11:19] == (
        "--set", "max_depth=5", "--set", 'mis="balance"', "--set", "rr=0.25", "--set", "lights=[1, 2]",
    )  # fmt: skip
    # Disjoint shard files across jobs and shards.
    states = [s.state for p in plans for s in p.shards]
    assert len(set(states)) == len(states) == 15


def test_no_integrator_means_the_scene_s_own():
    b = batch('[[jobs]]\nscene = "s.toml"\nspp = 4\n')
    (p,) = plan(b, "plexus")
    assert "--integrator" not in p.shards[0].argv
    assert p.shards[0].argv[-4:] == ("--shard", "0/1", "--out", str(shard_state_path(b, b.jobs[0], 0)))
    assert b.shard_dir == Path("/data/b/batch.shards")


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (True, "true"),
        (3, "3"),
        (0.1, "0.1"),
        (1e-300, "1e-300"),
        (float("inf"), "inf"),
        ("power", '"power"'),
        ('a"b\\c\n', '"a\\"b\\\\c\\n"'),
        ([0.5, "x"], '[0.5, "x"]'),
    ],
)
def test_settings_are_passed_as_toml_values_that_read_back_the_same(value, text):
    assert toml_value(value) == text
    assert tomllib.loads(f"v = {text}")["v"] == value


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no jobs"),
        ("jobs = []", "no jobs"),
        ("[[jobs]]\nspp = 1", "jobs[0]: missing scene"),
        ('[[jobs]]\nscene = "a.toml"', "jobs[0]: missing spp"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 0', "jobs[0]: spp: 0 is out of range"),
        ('[[jobs]]\nscene = "a.toml"\nspp = true', "jobs[0]: spp: expected an integer, got bool"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1.5', "jobs[0]: spp: expected an integer, got float"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nshards = 0', "jobs[0]: shards: 0 is out of range"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nseed = -1', "jobs[0]: seed: -1 is out of range"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nthreads = 2000', "jobs[0]: threads: 2000 is out of range"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nsamples = 4', "jobs[0]: unknown key 'samples'"),
        ('bogus = 1\n[[jobs]]\nscene = "a.toml"\nspp = 1', "unknown key 'bogus'"),
        ('[defaults]\nscene = "x"\n[[jobs]]\nscene = "a.toml"\nspp = 1', "[defaults]: unknown key 'scene'"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nname = "a/b"', "jobs[0]: name: expected letters"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\n[[jobs]]\nscene = "b/a.toml"\nspp = 1', "jobs[1]: name 'a' is already"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = ["x"]', "outputs: /data/b/x has no extension"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = []', "outputs: expected a non-empty list"),
        (
            '[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = ["o.exr"]\n[[jobs]]\nscene = "b.toml"\nspp = 1\noutputs = ["o.exr"]',
            "jobs[1]: output /data/b/o.exr is also written by job 'a'",
        ),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nsettings = { x = { y = 1 } }', "jobs[0]: settings.x: expected a number"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\nintegrator = 3', "jobs[0]: integrator: expected a name"),
        ('keep_shards = "yes"\n[[jobs]]\nscene = "a.toml"\nspp = 1', "keep_shards: expected true or false"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\ntimeout = -1', "jobs[0]: timeout: -1 is out of range"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\ntimeout = nan', "jobs[0]: timeout: nan is out of range"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\ntimeout = 1e10', "jobs[0]: timeout: 10000000000.0 is out of range"),
        ('[defaults]\ntimeout = "1h"\n[[jobs]]\nscene = "a.toml"\nspp = 1', "jobs[0]: timeout: expected seconds"),
        ('[[jobs]]\nscene = "a.toml"\nspp = 1\ntimeout = true', "jobs[0]: timeout: expected seconds"),
    ],
)
def test_bad_batch_files_are_one_line_errors_naming_the_key(text, message):
    with pytest.raises(BatchError) as e:
        batch(text)
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_timeouts_default_and_override():
    text = '[defaults]\ntimeout = 90\n[[jobs]]\nscene = "a.toml"\nspp = 1\n'
    text += '[[jobs]]\nscene = "b.toml"\nspp = 1\ntimeout = 0.5\n[[jobs]]\nscene = "c.toml"\nspp = 1\ntimeout = 0\n'
    a, b, c = batch(text).jobs
    assert (a.timeout, b.timeout, c.timeout) == (90.0, 0.5, None)  # 0: no timeout
    # Without a timeout in the file, the caller's default (the command line's --timeout), else an hour.
    (d,) = batch('[[jobs]]\nscene = "d.toml"\nspp = 1\n').jobs
    assert d.timeout == DEFAULT_TIMEOUT_S == 3600.0
    (e,) = parse(tomllib.loads('[[jobs]]\nscene = "e.toml"\nspp = 1\n'), Path("/b.toml"), default_timeout=None).jobs
    assert e.timeout is None
    # Every run of the job, its shards and its merge, has the job's timeout.
    (p,) = plan(batch(text), "plexus")[1:2]
    assert {s.timeout for s in p.shards} == {p.merge.timeout} == {0.5}


@pytest.mark.parametrize(
    ("outputs_a", "outputs_b", "message"),
    [
        # Two images with one stem: each job's merge writes x.json, one record replacing the other.
        (
            '["out/x.exr"]',
            '["out/y.exr", "out/x.png"]',
            "jobs[1]: output /data/b/out/x.png of job 'b' and output /data/b/out/x.exr of job 'a' share the stats"
            " JSON /data/b/out/x.json",
        ),
        ('["x.exr"]', '["sub/../x.exr"]', "jobs[1]: output /data/b/x.exr is also written by job 'a'"),
        ('["x.exr"]', '["x.json"]', "jobs[1]: output /data/b/x.json of job 'b' is the stats JSON of output /data/b/x.exr of job 'a'"),
        ('["x.json"]', '["x.exr"]', "jobs[1]: the stats JSON /data/b/x.json of output /data/b/x.exr of job 'b' is an output of job 'a'"),
    ],
)
def test_two_jobs_writing_one_file_are_refused(outputs_a, outputs_b, message):
    text = f'[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = {outputs_a}\n'
    text += f'[[jobs]]\nscene = "b.toml"\nspp = 1\noutputs = {outputs_b}\n'
    with pytest.raises(BatchError) as e:
        batch(text)
    assert message in str(e.value) and "\n" not in str(e.value)


def test_one_job_s_images_share_their_stats_json():
    # x.exr and x.png of one job: one merge writes x.json once, the same record for both.
    (job,) = batch('[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = ["x.exr", "x.png"]\n').jobs
    assert len(job.outputs) == 2


def test_the_same_file_through_a_symbolic_link_is_refused(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "out")
    b = tmp_path / "b.toml"
    b.write_text(
        '[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = ["out/x.exr"]\n'
        '[[jobs]]\nscene = "b.toml"\nspp = 1\noutputs = ["link/x.png"]\n'
    )
    with pytest.raises(BatchError, match=r"jobs\[1\]: output .*/link/x.png of job 'b' and output .*/out/x.exr of job 'a' share"):
        load(b)
    b.write_text(
        '[[jobs]]\nscene = "a.toml"\nspp = 1\noutputs = ["out/x.exr"]\n'
        '[[jobs]]\nscene = "b.toml"\nspp = 1\noutputs = ["link/x.exr"]\n'
    )
    with pytest.raises(BatchError, match=r"jobs\[1\]: output .*/link/x.exr \(the same file as .*/out/x.exr\) is also written by job 'a'"):
        load(b)


def test_load_reports_unreadable_and_malformed_files(tmp_path):
    with pytest.raises(BatchError, match="cannot read"):
        load(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[[jobs]\n")
    with pytest.raises(BatchError, match="not valid TOML"):
        load(bad)
    good = tmp_path / "good.toml"
    good.write_text('[[jobs]]\nscene = "s.toml"\nspp = 2\n')
    assert load(good).jobs[0].scene == tmp_path / "s.toml"


def test_find_plexus(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(FileNotFoundError, match="--plexus nope: not an executable file"):
        find_plexus("nope", cwd=tmp_path)
    binary = tmp_path / "target" / "release" / "plexus"
    binary.parent.mkdir(parents=True)
    binary.write_text("#!/bin/sh\n")
    binary.chmod(0o755)
    assert find_plexus(None, cwd=tmp_path) == binary
    assert find_plexus("target/release/plexus", cwd=tmp_path) == binary
    on_path = tmp_path / "bin" / "plexus"
    on_path.parent.mkdir()
    on_path.write_text("#!/bin/sh\n")
    on_path.chmod(0o755)
    monkeypatch.setenv("PATH", str(on_path.parent))
    assert find_plexus(None, cwd=tmp_path) == on_path


def test_dry_run_prints_the_commands(tmp_path, capsys):
    from plexus_batch.cli import main

    b = tmp_path / "b.toml"
    b.write_text('[[jobs]]\nscene = "s.toml"\nspp = 2\nshards = 2\nsettings = { mis = "power" }\n')
    binary = tmp_path / "plexus"
    binary.write_text("#!/bin/sh\n")
    binary.chmod(0o755)
    assert main([str(b), "--plexus", str(binary), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3
    assert shlex.split(lines[0])[-4:] == ["--shard", "0/2", "--out", str(tmp_path / "b.shards/s/shard-0-of-2.pxstate")]
    assert "mis=\"power\"" in shlex.split(lines[1])
    assert shlex.split(lines[2])[:2] == [str(binary), "merge"]


def test_cli_timeout_is_the_default_of_jobs_without_one(tmp_path, capsys, monkeypatch):
    import plexus_batch.cli as cli

    b = tmp_path / "b.toml"
    b.write_text('[[jobs]]\nscene = "s.toml"\nspp = 1\n[[jobs]]\nscene = "t.toml"\nspp = 1\ntimeout = 7\n')
    ran = []

    def run(batch, *_args):
        ran.append(batch)
        raise SystemExit(0)

    monkeypatch.setattr(cli, "_run", run)
    with pytest.raises(SystemExit):
        cli.main([str(b), "--plexus", "/bin/true", "--timeout", "60"])
    with pytest.raises(SystemExit):
        cli.main([str(b), "--plexus", "/bin/true", "--timeout", "0"])
    assert [[j.timeout for j in batch.jobs] for batch in ran] == [[60.0, 7.0], [None, 7.0]]
    assert cli.main([str(b), "--plexus", "/bin/true", "--timeout", "-5"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --timeout: -5.0 is out of range") and err.count("\n") == 1


def test_cli_bad_input_is_exit_2_with_one_line(tmp_path, capsys):
    from plexus_batch.cli import main

    b = tmp_path / "b.toml"
    b.write_text('[[jobs]]\nscene = "s.toml"\n')
    assert main([str(b), "--plexus", "/bin/true"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "missing spp" in err and err.count("\n") == 1
