"""Where --cluster points (pyramid_cli.run.cluster.connection), checked before Dask is imported; the address forms
against real sockets and schedulers: tests/system/test_dask.py."""

import sys

import pytest
from click.testing import CliRunner

from helpers.images import write_sequence
from pyramid_cli.cli import main
from pyramid_cli.core.errors import UsageError
from pyramid_cli.run.cluster import connection


def test_without_distributed_cluster_exits_2_naming_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(UsageError, match=r"pip install 'bilinear-pyramid\[cluster\]'"):
        connection.require()
    write_sequence(tmp_path / "in", 1, 2)
    r = CliRunner().invoke(main, ["blur", "--backend", "cpu", str(tmp_path / "in" / "plate.####.exr"),
                                  "-o", str(tmp_path / "out" / "o.####.exr"), "--cluster", "local:1"])
    assert r.exit_code == 2 and "bilinear-pyramid[cluster]" in r.output


def test_one_line_keeps_the_type_and_the_first_line():
    assert connection.one_line(OSError("refused\nmore detail")) == "OSError: refused"
    assert connection.one_line(TimeoutError()) == "TimeoutError"


def test_local_targets_need_a_worker_count():
    assert connection.resolve("local:3") == connection.Target("local:3", "local:3", local=3, scheme="local")
    for text in ("local:0", "local:x", "local:"):
        with pytest.raises(UsageError, match="expected local:N with N ≥ 1"):
            connection.resolve(text)


def test_a_port_out_of_range_is_refused_before_any_connection():
    with pytest.raises(UsageError, match="port 70000 is not a TCP port"):
        connection.resolve("tcp://127.0.0.1:70000", timeout=1)
