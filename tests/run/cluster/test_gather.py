"""The client's side of a cluster run (pyramid_cli.run.cluster.gather): chunking and naming the jobs not done.
Whole runs on real schedulers and workers: tests/system/test_dask.py."""

from types import SimpleNamespace

from pyramid_cli.run import cluster


def not_done(frames: list[int]) -> str:
    return cluster.describe_jobs([SimpleNamespace(frame=f, input="") for f in frames])


def test_chunks_and_default_size():
    assert cluster.chunks(list(range(7)), 3) == [[0, 1, 2], [3, 4, 5], [6]]
    assert cluster.default_chunk(30, 2) == 4 and cluster.default_chunk(10_000, 10) == cluster.MAX_CHUNK
    assert cluster.default_chunk(1, 8) == 1


def test_frames_not_done_read_as_runs():
    assert not_done([1005, 1006, 1007, 1008, 1020]) == "frames 1005-1008,1020"
    assert not_done([1001, 1003, 1005, 1007, 1010]) == "frames 1001-1007:2,1010"  # what --frames reads back
    assert not_done([7]) == "frame 7" and not_done([3, 4]) == "frames 3,4"
    jobs = [SimpleNamespace(input=f"in/{k}.exr") for k in range(7)]
    assert cluster.describe_jobs(jobs) == "in/0.exr, in/1.exr, in/2.exr, in/3.exr, in/4.exr and 2 more"
