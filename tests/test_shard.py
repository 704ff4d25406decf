"""Array-job shards: --shard K/N covers every job once; --shard auto under each scheduler's variables."""

from __future__ import annotations

import os

import pytest
from click.testing import CliRunner
from test_sequence import write_sequence

from pyramid_cli import sequence, shard
from pyramid_cli.cli import main
from pyramid_cli.errors import UsageError


@pytest.mark.parametrize("n", [1, 2, 3, 7])
def test_every_k_of_n_covers_each_frame_exactly_once(tmp_path, n):
    jobs = sequence.plan_jobs([str(tmp_path / "plate.1001-1020#.exr")], str(tmp_path / "o.####.exr"))
    seen = []
    for k in range(1, n + 1):
        part = shard.select(jobs, f"{k}/{n}")
        frames = [j.frame for j in part]
        assert frames == list(range(frames[0], frames[0] + len(frames)))  # contiguous
        assert len(part) in (20 // n, -(-20 // n))                       # balanced
        seen += frames
    assert seen == list(range(1001, 1021))


def test_more_shards_than_jobs_gives_empty_shards():
    parts = [shard.select(list(range(3)), f"{k}/5") for k in range(1, 6)]
    assert sum(parts, []) == [0, 1, 2] and [] in parts


@pytest.mark.parametrize("spec", ["0/4", "5/4", "3", "1/0", "a/b", "auto/0", ""])
def test_bad_specs_are_usage_errors(spec):
    with pytest.raises(UsageError):
        shard.parse(spec, env={"SLURM_ARRAY_TASK_ID": "1", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_COUNT": "2"})


@pytest.mark.parametrize("env, count, expected", [
    # Slurm: --array=1-10 (COUNT given), --array=0-9, --array=1-20:2 (a step)
    ({"SLURM_ARRAY_TASK_ID": "3", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "10",
      "SLURM_ARRAY_TASK_COUNT": "10"}, None, (2, 10)),
    ({"SLURM_ARRAY_TASK_ID": "0", "SLURM_ARRAY_TASK_MIN": "0", "SLURM_ARRAY_TASK_MAX": "9"}, None, (0, 10)),
    ({"SLURM_ARRAY_TASK_ID": "5", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "19",
      "SLURM_ARRAY_TASK_STEP": "2", "SLURM_ARRAY_TASK_COUNT": "10"}, None, (2, 10)),
    # SGE/UGE: qsub -t 1-10, qsub -t 2-20:2
    ({"SGE_TASK_ID": "10", "SGE_TASK_FIRST": "1", "SGE_TASK_LAST": "10", "SGE_TASK_STEPSIZE": "1"}, None, (9, 10)),
    ({"SGE_TASK_ID": "6", "SGE_TASK_FIRST": "2", "SGE_TASK_LAST": "20", "SGE_TASK_STEPSIZE": "2"}, None, (2, 10)),
    # AWS Batch and Kubernetes: 0-based, count from auto/N or PYRAMID_SHARD_COUNT
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "0"}, 8, (0, 8)),
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "7", "PYRAMID_SHARD_COUNT": "8"}, None, (7, 8)),
    ({"JOB_COMPLETION_INDEX": "4"}, 5, (4, 5)),
    ({"JOB_COMPLETION_INDEX": "1", "PYRAMID_SHARD_COUNT": "5"}, None, (1, 5)),
    # LSF: bsub -J 'x[1-10]' sets LSB_JOBINDEX_END; PBS Pro -J 1-N; Torque -t 1-N
    ({"LSB_JOBINDEX": "4", "LSB_JOBINDEX_END": "10"}, None, (3, 10)),
    ({"LSB_JOBINDEX": "4"}, 6, (3, 6)),
    ({"PBS_ARRAY_INDEX": "1"}, 4, (0, 4)),
    ({"PBS_ARRAYID": "2", "PYRAMID_SHARD_COUNT": "4"}, None, (1, 4)),
])
def test_auto_under_each_scheduler(env, count, expected):
    s = shard.parse("auto" if count is None else f"auto/{count}", env=env)
    assert (s.index, s.count) == expected


@pytest.mark.parametrize("env, message", [
    ({}, "not in an array task"),
    ({"SGE_TASK_ID": "undefined"}, "not in an array task"),
    ({"LSB_JOBINDEX": "0"}, "not in an array task"),
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "3"}, "auto/N or set PYRAMID_SHARD_COUNT"),
    ({"JOB_COMPLETION_INDEX": "3"}, "auto/N or set PYRAMID_SHARD_COUNT"),
    ({"JOB_COMPLETION_INDEX": "9", "PYRAMID_SHARD_COUNT": "4"}, "outside the array"),
    ({"SLURM_ARRAY_TASK_ID": "x"}, "not a whole number"),
])
def test_auto_without_a_shard_is_a_usage_error(env, message):
    with pytest.raises(UsageError, match=message):
        shard.parse("auto", env=env)


def test_stale_temporary_files_are_removed(tmp_path):
    (tmp_path / ".o.0001.exr.tmp-abc123.exr").write_bytes(b"half")
    (tmp_path / ".o.0002.exr.tmp-abc123.exr").write_bytes(b"someone else's")
    assert shard.remove_stale_temps([str(tmp_path / "o.0001.exr")]) == 1
    assert os.listdir(tmp_path) == [".o.0002.exr.tmp-abc123.exr"]


@pytest.mark.cli
def test_cli_shards_cover_the_sequence_once_and_auto_reads_slurm(tmp_path, monkeypatch):
    write_sequence(tmp_path / "in", 1, 20)
    base = ["blur", "--backend", "cpu", "--levels", "1", str(tmp_path / "in" / "plate.####.exr"),
            "-o", str(tmp_path / "out" / "soft.####.exr")]
    runner = CliRunner()
    r = runner.invoke(main, [*base, "--shard", "1/3"])
    assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path / "out")) == [f"soft.{f:04d}.exr" for f in range(1, 7)]
    r = runner.invoke(main, [*base, "--shard", "auto"],
                      env={"SLURM_ARRAY_TASK_ID": "2", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_COUNT": "3"})
    assert r.exit_code == 0, r.output
    assert len(os.listdir(tmp_path / "out")) == 13
    r = runner.invoke(main, [*base, "--shard", "3/3", "--skip-existing"])
    assert r.exit_code == 0 and sorted(os.listdir(tmp_path / "out")) == [f"soft.{f:04d}.exr" for f in range(1, 21)]
    r = runner.invoke(main, [*base, "--shard", "3/3", "--skip-existing"])  # a retry does only what is missing
    assert "0 written, 7 up to date" in r.output
    for var in [v for _, v, _ in shard.SCHEDULERS]:
        monkeypatch.delenv(var, raising=False)
    r = runner.invoke(main, [*base, "--shard", "auto"])
    assert r.exit_code == 2 and "not in an array task" in r.output
