"""The Dask runner on a LocalCluster on 127.0.0.1: same bytes as one process, a worker killed mid-job."""

from __future__ import annotations

import os
import sys

import pytest
from click.testing import CliRunner
from test_sequence import write_sequence

import pyramid_cli as pyr
from pyramid_cli import cluster
from pyramid_cli.cli import main
from pyramid_cli.errors import UsageError

WORK = pyr.Blur(levels=2)


def outputs(folder):
    return sorted(os.listdir(folder))


def test_without_distributed_cluster_exits_2_naming_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(UsageError, match=r"pip install 'bilinear-pyramid\[cluster\]'"):
        cluster.require()
    write_sequence(tmp_path / "in", 1, 2)
    r = CliRunner().invoke(main, ["blur", "--backend", "cpu", str(tmp_path / "in" / "plate.####.exr"),
                                  "-o", str(tmp_path / "out" / "o.####.exr"), "--cluster", "local:1"])
    assert r.exit_code == 2 and "bilinear-pyramid[cluster]" in r.output


def test_chunks_and_default_size():
    assert cluster.chunks(list(range(7)), 3) == [[0, 1, 2], [3, 4, 5], [6]]
    assert cluster.default_chunk(30, 2) == 4 and cluster.default_chunk(10_000, 10) == cluster.MAX_CHUNK
    assert cluster.default_chunk(1, 8) == 1


@pytest.mark.slow
def test_local_cluster_matches_one_process_and_survives_a_killed_worker(tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")
    write_sequence(tmp_path / "in", 1001, 1030, size=(32, 32))
    pattern = str(tmp_path / "in" / "plate.####.exr")
    assert pyr.process_files(WORK, [pattern], template=str(tmp_path / "one" / "soft.####.exr"), backend="cpu") == 0

    flag = tmp_path / "crashed"
    monkeypatch.setenv(cluster.CRASH_VARIABLE, str(flag))  # inherited by the worker processes
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None) as local, distributed.Client(local) as client:
        code = pyr.process_files(WORK, [pattern], template=str(tmp_path / "many" / "soft.####.exr"),
                                 backend="cpu", cluster=client, chunk=5)
        assert all(addr.startswith("tcp://127.0.0.1:") for addr in client.scheduler_info()["workers"])
    assert code == 0
    assert flag.exists()  # a worker did die half-way through a chunk
    names = outputs(tmp_path / "one")
    assert len(names) == 30 and outputs(tmp_path / "many") == names  # no temporary file left, nothing extra
    for name in names:
        assert (tmp_path / "many" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name


@pytest.mark.slow
@pytest.mark.cli
def test_cli_cluster_keep_going_and_exit_code_as_one_process(tmp_path):
    pytest.importorskip("distributed")
    write_sequence(tmp_path / "in", 1, 8)
    (tmp_path / "in" / "plate.0005.exr").write_text("not an exr")
    r = CliRunner().invoke(main, ["blur", "--backend", "cpu", "--levels", "2", str(tmp_path / "in" / "plate.####.exr"),
                                  "-o", str(tmp_path / "out" / "soft.####.exr"), "--cluster", "local:2",
                                  "--chunk", "3", "--keep-going"])
    assert r.exit_code == 3, r.output
    assert "plate.0005.exr" in r.output and "7 written, 0 up to date, 1 failed" in r.output
    assert len(outputs(tmp_path / "out")) == 7


@pytest.mark.cli
def test_unreachable_scheduler_and_bad_local_spec_exit_2(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "0.5s")
    write_sequence(tmp_path / "in", 1, 2)
    base = ["blur", "--backend", "cpu", str(tmp_path / "in" / "plate.####.exr"), "-o", str(tmp_path / "o.####.exr")]
    r = CliRunner().invoke(main, [*base, "--cluster", "tcp://127.0.0.1:9"])  # the discard port: nothing listens
    assert r.exit_code == 2 and "cannot reach a Dask scheduler" in r.output
    r = CliRunner().invoke(main, [*base, "--cluster", "local:0"])
    assert r.exit_code == 2 and "local:N" in r.output


def test_api_takes_frames_and_shards(tmp_path):
    write_sequence(tmp_path / "in", 1, 6)
    kw = {"template": str(tmp_path / "out" / "o.{frame}.exr"), "backend": "cpu", "frames": "1-6x1"}
    assert pyr.process_files(WORK, [str(tmp_path / "in" / "plate.####.exr")], shard="2/3", **kw) == 0
    assert outputs(tmp_path / "out") == ["o.3.exr", "o.4.exr"]
