"""Array-job shards: --shard K/N covers every job once; --shard auto under each scheduler's variables."""

from __future__ import annotations

import os

import pytest
from click.testing import CliRunner

from helpers.images import write_sequence
from helpers.marks import slow_beyond
from pyramid_cli.cli import main
from pyramid_cli.core.errors import UsageError
from pyramid_cli.run import sequence, shard


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


@pytest.mark.parametrize("spec", ["0/4", "5/4", "3", "1/0", "a/b", "auto/0", "", "auto/5-3", "auto/1-9:0", "auto/-1-4",
                                  "auto/1-4:"])
def test_bad_specs_are_usage_errors(spec):
    with pytest.raises(UsageError):
        shard.parse(spec, env={"SLURM_ARRAY_TASK_ID": "1", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_COUNT": "2"})


@pytest.mark.parametrize("env, spec, expected", [
    # Slurm: --array=1-10, --array=0-9 (a Slurm without COUNT: the count from MAX), --array=1-20:2
    ({"SLURM_ARRAY_TASK_ID": "3", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "10",
      "SLURM_ARRAY_TASK_STEP": "1", "SLURM_ARRAY_TASK_COUNT": "10"}, "auto", (2, 10)),
    ({"SLURM_ARRAY_TASK_ID": "0", "SLURM_ARRAY_TASK_MIN": "0", "SLURM_ARRAY_TASK_MAX": "9",
      "SLURM_ARRAY_TASK_STEP": "1"}, "auto", (0, 10)),
    ({"SLURM_ARRAY_TASK_ID": "5", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "19",
      "SLURM_ARRAY_TASK_STEP": "2", "SLURM_ARRAY_TASK_COUNT": "10"}, "auto", (2, 10)),
    # SGE/UGE: qsub -t 1-10, qsub -t 2-20:2
    ({"SGE_TASK_ID": "10", "SGE_TASK_FIRST": "1", "SGE_TASK_LAST": "10", "SGE_TASK_STEPSIZE": "1"}, "auto", (9, 10)),
    ({"SGE_TASK_ID": "6", "SGE_TASK_FIRST": "2", "SGE_TASK_LAST": "20", "SGE_TASK_STEPSIZE": "2"}, "auto", (2, 10)),
    # AWS Batch and Kubernetes: from 0; the count from AWS_BATCH_JOB_ARRAY_SIZE, auto/N or PYRAMID_SHARD_COUNT
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "0"}, "auto/8", (0, 8)),
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "7", "PYRAMID_SHARD_COUNT": "8"}, "auto", (7, 8)),
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "7", "AWS_BATCH_JOB_ARRAY_SIZE": "8"}, "auto", (7, 8)),
    ({"JOB_COMPLETION_INDEX": "4"}, "auto/5", (4, 5)),
    ({"JOB_COMPLETION_INDEX": "1", "PYRAMID_SHARD_COUNT": "5"}, "auto", (1, 5)),
    ({"JOB_COMPLETION_INDEX": "1"}, "auto/0-4", (1, 5)),
    # LSF: bsub -J 'x[1-10]' publishes the index and the end, not the start: the range is given
    ({"LSB_JOBINDEX": "4", "LSB_JOBINDEX_END": "10"}, "auto/1-10", (3, 10)),
    ({"LSB_JOBINDEX": "7", "LSB_JOBINDEX_END": "9", "LSB_JOBINDEX_STEP": "1"}, "auto/5-9", (2, 5)),
    ({"LSB_JOBINDEX": "7", "LSB_JOBINDEX_END": "10", "LSB_JOBINDEX_STEP": "3"}, "auto/1-10:3", (2, 4)),
    ({"LSB_JOBINDEX": "4"}, "auto/1-6", (3, 6)),
    # PBS Pro -J 1-4 and -J 0-3, Torque -t 1-4: nothing but the index is published
    ({"PBS_ARRAY_INDEX": "1"}, "auto/1-4", (0, 4)),
    ({"PBS_ARRAY_INDEX": "1"}, "auto/0-3", (1, 4)),
    ({"PBS_ARRAY_INDEX": "4", "PYRAMID_SHARD_ARRAY": "0-8:2"}, "auto", (2, 5)),
    ({"PBS_ARRAYID": "2", "PYRAMID_SHARD_ARRAY": "1-4"}, "auto", (1, 4)),
    ({"PBS_ARRAYID": "2", "PYRAMID_SHARD_ARRAY": "1-4%2"}, "auto/4", (1, 4)),  # a %LIMIT as submitted
])
def test_auto_under_each_scheduler(env, spec, expected):
    s = shard.parse(spec, env=env)
    assert (s.index, s.count) == expected


@pytest.mark.parametrize("env, spec, message", [
    ({}, "auto", "not in an array task"),
    ({"SGE_TASK_ID": "undefined"}, "auto", "not in an array task"),
    ({"LSB_JOBINDEX": "0"}, "auto", "not in an array task"),
    ({"AWS_BATCH_JOB_ARRAY_INDEX": "3"}, "auto", "auto/N or set PYRAMID_SHARD_COUNT"),
    ({"JOB_COMPLETION_INDEX": "3"}, "auto", "auto/N or set PYRAMID_SHARD_COUNT"),
    ({"JOB_COMPLETION_INDEX": "9", "PYRAMID_SHARD_COUNT": "4"}, "auto", r"JOB_COMPLETION_INDEX=9 is outside the array"),
    ({"SLURM_ARRAY_TASK_ID": "x"}, "auto", "not a whole number"),
    # the two reports: LSF from 5 (was: chunks of 9 from 1, frames lost) and PBS from 0 (was: task 0 failed)
    ({"LSB_JOBINDEX": "5", "LSB_JOBINDEX_END": "9", "LSB_JOBINDEX_STEP": "1"}, "auto",
     r"LSF job array does not publish its first index: .*auto/5-9 .*\(read LSB_JOBINDEX=5, LSB_JOBINDEX_END=9"),
    ({"LSB_JOBINDEX": "4", "LSB_JOBINDEX_END": "10"}, "auto/10", "does not publish its first index"),
    ({"PBS_ARRAY_INDEX": "0"}, "auto/4", r"PBS Pro array job does not publish its first index or step: .*auto/0-3"),
    ({"PBS_ARRAYID": "2", "PYRAMID_SHARD_COUNT": "4"}, "auto", "Torque array job does not publish"),
    ({"PBS_ARRAY_INDEX": "0"}, "auto/1-4", r"PBS_ARRAY_INDEX=0 is outside the array 1-4"),
    ({"PBS_ARRAY_INDEX": "2"}, "auto/1-9:2", r"PBS_ARRAY_INDEX=2 is not an index of the array 1-9:2"),
    ({"SLURM_ARRAY_TASK_ID": "3", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "10",
      "SLURM_ARRAY_TASK_STEP": "1", "SLURM_ARRAY_TASK_COUNT": "10"}, "auto/8",
     r"the task count is 10 by SLURM_ARRAY_TASK_COUNT but 8 by --shard auto/8"),
    ({"PBS_ARRAY_INDEX": "2", "PYRAMID_SHARD_ARRAY": "1-4"}, "auto/0-3",
     r"the first index is 0 by --shard auto/0-3 but 1 by PYRAMID_SHARD_ARRAY"),
])
def test_auto_without_a_shard_is_a_usage_error(env, spec, message):
    with pytest.raises(UsageError, match=message):
        shard.parse(spec, env=env)


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
                      env={"SLURM_ARRAY_TASK_ID": "2", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "3",
                           "SLURM_ARRAY_TASK_STEP": "1", "SLURM_ARRAY_TASK_COUNT": "3"})
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


# --- Every scheduler, simulated: each array task's environment as the scheduler sets it ---------------------------
# An array spec is (first, last, step) as submitted; each function gives the environment of every task, or None
# where the scheduler cannot run such an array (SGE and LSF index from 1, AWS Batch and Kubernetes from 0 by 1).

def _indices(first, last, step):
    return list(range(first, last + 1, step))


def slurm(first, last, step):  # sbatch --array=FIRST-LAST:STEP; MAX is the last index, not LAST
    ids = _indices(first, last, step)
    return [{"SLURM_ARRAY_JOB_ID": "77", "SLURM_ARRAY_TASK_ID": str(i), "SLURM_ARRAY_TASK_MIN": str(ids[0]),
             "SLURM_ARRAY_TASK_MAX": str(ids[-1]), "SLURM_ARRAY_TASK_STEP": str(step),
             "SLURM_ARRAY_TASK_COUNT": str(len(ids))} for i in ids]


def sge(first, last, step):  # qsub -t FIRST-LAST:STEP
    if first < 1:
        return None
    return [{"SGE_TASK_ID": str(i), "SGE_TASK_FIRST": str(first), "SGE_TASK_LAST": str(last),
             "SGE_TASK_STEPSIZE": str(step)} for i in _indices(first, last, step)]


def aws_batch(first, last, step):  # arrayProperties.size = N
    if first != 0 or step != 1:
        return None
    return [{"AWS_BATCH_JOB_ARRAY_INDEX": str(i), "AWS_BATCH_JOB_ARRAY_SIZE": str(last + 1),
             "AWS_BATCH_JOB_ID": f"abc:{i}"} for i in range(last + 1)]


def kubernetes(first, last, step):  # completionMode: Indexed, completions: N
    if first != 0 or step != 1:
        return None
    return [{"JOB_COMPLETION_INDEX": str(i)} for i in range(last + 1)]


def lsf(first, last, step, name=False):  # bsub -J 'x[FIRST-LAST:STEP]': the index, the end, the step
    if first < 1:
        return None
    envs = [{"LSB_JOBID": "77", "LSB_JOBINDEX": str(i), "LSB_JOBINDEX_END": str(last),
             "LSB_JOBINDEX_STEP": str(step)} for i in _indices(first, last, step)]
    if name:  # OpenLava's sbatchd also sets LSB_JOBNAME to the name as submitted (IBM does not document it)
        for env in envs:
            env["LSB_JOBNAME"] = f"x[{first}-{last}:{step}]"
    return envs


def pbs_pro(first, last, step):  # qsub -J FIRST-LAST:STEP
    return [{"PBS_ARRAY_INDEX": str(i), "PBS_ARRAY_ID": "77[].server", "PBS_JOBID": f"77[{i}].server"}
            for i in _indices(first, last, step)]


def torque(first, last, step):  # qsub -t FIRST-LAST (Torque has no step: a comma list)
    return [{"PBS_ARRAYID": str(i), "PBS_JOBID": f"77[{i}].server"} for i in _indices(first, last, step)]


SIMULATED = {"slurm": slurm, "sge": sge, "aws_batch": aws_batch, "kubernetes": kubernetes, "lsf": lsf,
             "lsf_named": lambda *a: lsf(*a, name=True), "pbs_pro": pbs_pro, "torque": torque}
#: What each scheduler needs the user to give: nothing, the count, or the range.
NEEDS = {"slurm": None, "sge": None, "aws_batch": None, "kubernetes": "count", "lsf": "range",
         "lsf_named": "range", "pbs_pro": "range", "torque": "range"}
ARRAYS = [(0, 3, 1), (1, 4, 1), (5, 9, 1), (0, 9, 2), (1, 10, 2), (5, 20, 3), (1, 1, 1), (0, 6, 1)]


def _given(way, first, last, step):
    """(--shard spec, extra environment) for one way of giving the array's facts."""
    count, span = len(_indices(first, last, step)), f"{first}-{last}" + (f":{step}" if step != 1 else "")
    return {"nothing": ("auto", {}), "auto/N": (f"auto/{count}", {}), "auto/RANGE": (f"auto/{span}", {}),
            "ARRAY": ("auto", {"PYRAMID_SHARD_ARRAY": span}), "COUNT": ("auto", {"PYRAMID_SHARD_COUNT": str(count)}),
            "auto/N+ARRAY": (f"auto/{count}", {"PYRAMID_SHARD_ARRAY": span})}[way]


def run_array(envs, spec, extra, jobs):
    """Every task's chunk of ``jobs``, or every task's UsageError; a mixture fails the test."""
    chunks, errors = [], []
    for env in envs:
        try:
            chunks.append(shard.select(jobs, shard.parse(spec, env={**env, **extra})))
        except UsageError as e:
            errors.append(str(e))
    assert not (chunks and errors), f"a mixture: {len(chunks)} task(s) ran, {len(errors)} refused: {errors[0]}"
    if chunks:
        done = [job for chunk in chunks for job in chunk]
        assert sorted(done) == list(jobs), "every job exactly once"
    return errors


@pytest.mark.parametrize("scheduler", slow_beyond(sorted(SIMULATED), 3))
@pytest.mark.parametrize("way", ["nothing", "auto/N", "auto/RANGE", "ARRAY", "COUNT", "auto/N+ARRAY"])
def test_every_scheduler_does_every_job_once_or_every_task_refuses(scheduler, way):
    simulated = 0
    for first, last, step in ARRAYS:
        envs = SIMULATED[scheduler](first, last, step)
        if envs is None:
            continue
        simulated += 1
        spec, extra = _given(way, first, last, step)
        for total in (24, 7, 2, 0):  # counts that do not divide; fewer jobs than tasks; none
            errors = run_array(envs, spec, extra, list(range(total)))
            need = NEEDS[scheduler]
            gives_range = way in ("auto/RANGE", "ARRAY", "auto/N+ARRAY")
            expected = need is None or gives_range or need == "count" and way != "nothing"
            assert (not errors) == expected, (first, last, step, errors[:1])
            assert all("(read " in e for e in errors)  # each refusal names the variables it read
    assert simulated >= 2


PUBLISHED = ("slurm", "sge", "aws_batch")  # publish first, step and count
INCONSISTENT = [  # (--shard, environment, the schedulers where every task must refuse)
    ("auto/{n1}", {}, (*PUBLISHED, "lsf", "lsf_named", "pbs_pro", "torque")),   # a count one too many
    ("auto/{r1}", {}, (*PUBLISHED, "lsf", "lsf_named")),                        # a range one task too long
    ("auto/{r_late}", {}, (*PUBLISHED, "kubernetes", "lsf_named")),             # a range starting one late
    ("auto/{n0}", {"PYRAMID_SHARD_COUNT": "{n1}"}, tuple(SIMULATED)),            # the user's counts disagree
    ("auto/{r}", {"PYRAMID_SHARD_ARRAY": "{r1}"}, tuple(SIMULATED)),             # the user's ranges disagree
    ("auto", {"PYRAMID_SHARD_ARRAY": "{r}", "PYRAMID_SHARD_COUNT": "{n1}"}, tuple(SIMULATED)),
    ("auto", {"PYRAMID_SHARD_ARRAY": "{r}x"}, tuple(SIMULATED)),                 # not a range
]


@pytest.mark.parametrize("spec, extra, schedulers", INCONSISTENT)
def test_inconsistent_facts_make_every_task_refuse(spec, extra, schedulers):
    for scheduler in schedulers:
        for first, last, step in ARRAYS:
            envs = SIMULATED[scheduler](first, last, step)
            if envs is None or len(envs) < 2:
                continue
            keys = {"n0": len(envs), "n1": len(envs) + 1, "r": f"{first}-{last}:{step}",
                    "r1": f"{first}-{last + step}:{step}", "r_late": f"{first + 1}-{last}:{step}"}
            given = {k: v.format(**keys) for k, v in extra.items()}
            errors = run_array(envs, spec.format(**keys), given, list(range(24)))
            assert len(errors) == len(envs), (scheduler, first, last, step, spec, given)


@pytest.mark.parametrize("envs", [
    # sbatch --array=1,3,7 and --array=1-5,10 and --array=0-4:2,7: MIN/MAX/STEP/COUNT as Slurm sets them
    [{"SLURM_ARRAY_TASK_ID": str(i), "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "7",
      "SLURM_ARRAY_TASK_STEP": "1", "SLURM_ARRAY_TASK_COUNT": "3"} for i in (1, 3, 7)],
    [{"SLURM_ARRAY_TASK_ID": str(i), "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "10",
      "SLURM_ARRAY_TASK_STEP": "1", "SLURM_ARRAY_TASK_COUNT": "6"} for i in (1, 2, 3, 4, 5, 10)],
    [{"SLURM_ARRAY_TASK_ID": str(i), "SLURM_ARRAY_TASK_MIN": "0", "SLURM_ARRAY_TASK_MAX": "7",
      "SLURM_ARRAY_TASK_STEP": "2", "SLURM_ARRAY_TASK_COUNT": "4"} for i in (0, 2, 4, 7)],
    # bsub -J 'x[11-15,20-24]': OpenLava gives each task its own sub-range's END; LSB_JOBNAME shows the list
    [{"LSB_JOBINDEX": str(i), "LSB_JOBINDEX_END": "15" if i <= 15 else "24", "LSB_JOBINDEX_STEP": "1",
      "LSB_JOBNAME": "x[11-15,20-24]"} for i in (11, 12, 13, 14, 15, 20, 21, 22, 23, 24)],
])
@pytest.mark.parametrize("spec", ["auto", "auto/10", "auto/11-24", "auto/1-10"])
def test_an_irregular_list_makes_every_task_refuse(envs, spec):
    errors = run_array(envs, spec, {}, list(range(24)))
    assert len(errors) == len(envs)


@pytest.mark.parametrize("spec, extra", [("auto", {}), ("auto/10", {}), ("auto", {"PYRAMID_SHARD_COUNT": "10"})])
def test_lsf_needs_the_range_not_a_count(spec, extra):
    """bsub -J 'x[11-15,20-24]': each task sees its own sub-range's END, so FIRST = END − (N−1)·STEP would put
    both sub-ranges on chunks 5–9 of 10 and do chunks 0–4 nowhere; a count alone is refused in every task."""
    envs = [{"LSB_JOBINDEX": str(i), "LSB_JOBINDEX_END": "15" if i <= 15 else "24", "LSB_JOBINDEX_STEP": "1"}
            for i in (11, 12, 13, 14, 15, 20, 21, 22, 23, 24)]
    errors = run_array(envs, spec, extra, list(range(24)))
    assert len(errors) == 10 and all("does not publish its first index" in e for e in errors)


def test_lsf_job_name_with_only_the_task_index_says_nothing():
    s = shard.parse("auto/5-9", env={"LSB_JOBINDEX": "7", "LSB_JOBINDEX_END": "9", "LSB_JOBNAME": "x[7]"})
    assert (s.index, s.count) == (2, 5)


def test_verbose_source_says_where_each_fact_came_from():
    s = shard.parse("auto/5-9", env=lsf(5, 9, 1)[2])
    assert s.source == ("LSB_JOBINDEX=7 of 5-9: first index from --shard auto/5-9; step from LSB_JOBINDEX_STEP; "
                        "task count from --shard auto/5-9")
    s = shard.parse("auto", env=slurm(1, 20, 2)[3])
    assert s.source.startswith("SLURM_ARRAY_TASK_ID=7 of 1-19:2: first index from SLURM_ARRAY_TASK_MIN")


def _blur_sequence(tmp_path, first, last):
    """Frames ``first``–``last`` on disk; the output folder and a blur command over them without --shard."""
    write_sequence(tmp_path / "in", first, last)
    out = tmp_path / "out"
    return out, ["blur", "--backend", "cpu", "--levels", "1", str(tmp_path / "in" / "plate.####.exr"),
                 "-o", str(out / "soft.####.exr")]


@pytest.mark.cli
def test_cli_lsf_array_from_5_refuses_without_its_start_and_does_each_frame_once_with_it(tmp_path):
    """The issue's report: bsub -J 'x[5-9]' over 24 frames wrote 14 and every task exited 0."""
    out, base = _blur_sequence(tmp_path, 1001, 1024)
    runner = CliRunner()
    for env in lsf(5, 9, 1):
        r = runner.invoke(main, [*base, "--shard", "auto"], env=env)
        assert r.exit_code == 2 and "LSB_JOBINDEX_END=9" in r.output and "auto/FIRST-LAST" in r.output, r.output
    assert not out.exists() or not os.listdir(out)
    written = 0
    for env in lsf(5, 9, 1):
        r = runner.invoke(main, [*base, "--shard", "auto/5-9", "-v"], env=env)
        assert r.exit_code == 0, r.output
        assert "of 5-9: first index from --shard auto/5-9" in r.output
        written += int(r.output.rsplit(" written", 1)[0].split()[-1])
    assert written == 24
    assert sorted(os.listdir(out)) == [f"soft.{f}.exr" for f in range(1001, 1025)]


@pytest.mark.cli
def test_cli_pbs_array_from_0_does_each_frame_once(tmp_path):
    """The issue's report: PBS -J 0-3 with auto/4: task 0 exited 2 and its frames were never done."""
    out, base = _blur_sequence(tmp_path, 1, 10)
    runner = CliRunner()
    for env in pbs_pro(0, 3, 1):  # a count alone cannot place a PBS task: every task refuses
        r = runner.invoke(main, [*base, "--shard", "auto/4"], env=env)
        assert r.exit_code == 2 and "PBS_ARRAY_INDEX=" in r.output, r.output
    assert not out.exists() or not os.listdir(out)
    for env in pbs_pro(0, 3, 1):
        r = runner.invoke(main, [*base, "--shard", "auto/0-3"], env=env)
        assert r.exit_code == 0, r.output
    assert sorted(os.listdir(out)) == [f"soft.{f:04d}.exr" for f in range(1, 11)]
