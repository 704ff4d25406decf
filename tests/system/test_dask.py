"""The Dask runner: one process's report wherever the work ran.

Real ``dask scheduler`` and ``dask worker`` processes (tests/dask_processes.py) and the
``pyramid`` command as a subprocess, so that its standard error is what a terminal would
show: a chunk failing with and without --keep-going, a worker killed mid-chunk, the
scheduler killed, every worker lost, a chunk the cluster gives up on, and the address
forms. Also a LocalCluster on 127.0.0.1 (``local:N`` and a Client through the API).
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

import pyramid_cli as pyr
from helpers.dask_processes import DaskProcesses
from helpers.images import write_sequence
from pyramid_cli.cli import main
from pyramid_cli.core.errors import UsageError
from pyramid_cli.run import cluster

WORK = pyr.Blur(levels=2)
HANG = 120  # seconds after which a run counts as hung: far beyond any run here, even on a loaded machine


def outputs(folder):
    return sorted(os.listdir(folder)) if os.path.isdir(folder) else []


def pyramid(*args, timeout: float = HANG) -> SimpleNamespace:
    """The command in a process of its own: exit code, standard output and error lines, wall time."""
    start = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "pyramid_cli.cli", *map(str, args)], capture_output=True, text=True,
                       timeout=timeout)
    return SimpleNamespace(code=r.returncode, out=r.stdout.splitlines(), err=r.stderr.splitlines(),
                           seconds=time.monotonic() - start)


def only_ours(lines: list[str]) -> bool:
    """No line of Dask's (or a traceback) on standard error: every line is one of this tool's."""
    return all(line.startswith("pyramid:") for line in lines if line.strip())


def frames_of(lines: list[str]) -> list[int]:
    return [int(m.group(1)) for line in lines if (m := re.search(r"soft\.(\d+)\.exr", line))]


def not_done(frames: list[int]) -> str:
    return cluster.describe_jobs([SimpleNamespace(frame=f, input="") for f in frames])


def expand(text: str) -> list[int]:
    """``frames 3-5,9`` back to [3, 4, 5, 9], as --frames reads it."""
    from pyramid_cli.run.sequence import frame_set

    return frame_set(text.split(" ", 1)[1])


def moved(lines: list[str], a: str, b: str) -> list[str]:
    """A local run's lines as they read for outputs in folder ``b`` instead of ``a``."""
    return [line.replace(f"{os.sep}{a}{os.sep}", f"{os.sep}{b}{os.sep}") for line in lines]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed again: nothing listens there


@pytest.fixture
def dask_cluster(tmp_path):
    """``start(env, n)``: a scheduler and n worker processes on 127.0.0.1, always killed at the end of the test."""
    pytest.importorskip("distributed")
    started: list[DaskProcesses] = []

    def start(env: dict[str, str] | None = None, n: int = 2) -> DaskProcesses:
        procs = DaskProcesses(tmp_path / f"dask{len(started)}", env)
        started.append(procs)
        procs.start_scheduler()
        procs.start_workers(n)
        return procs

    yield start
    for procs in started:
        procs.close()


def blur(tmp_path, out: str, *extra):
    return ["blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "plate.####.exr",
            "-o", tmp_path / out / "soft.####.exr", *extra]


# ------------------------------------------------------------------ without a cluster
# (require(), chunking and describe_jobs alone: tests/run/cluster/test_connection.py, test_gather.py)
@pytest.mark.cli
def test_chunk_and_cluster_timeout_without_cluster_are_refused(tmp_path):
    write_sequence(tmp_path / "in", 1, 2)
    for option in (["--chunk", "2"], ["--cluster-timeout", "5"]):
        r = CliRunner().invoke(main, [*map(str, blur(tmp_path, "out")), *option])
        assert r.exit_code == 2 and "are for --cluster runs" in r.output, r.output
    assert outputs(tmp_path / "out") == []


# ------------------------------------------------------------------ addresses
@pytest.mark.cli
@pytest.mark.slow
def test_refused_connection_is_one_line_within_seconds(tmp_path):
    """The issue asks for under 2 s on localhost; 5 s here leaves room for a loaded 2-core machine (Dask itself
    retried for 20 s)."""
    pytest.importorskip("distributed")
    write_sequence(tmp_path / "in", 1, 2)
    port = free_port()
    for address in (f"tcp://127.0.0.1:{port}", f"127.0.0.1:{port}", f"ws://127.0.0.1:{port}"):
        r = pyramid(*blur(tmp_path, "out", "--cluster", address))
        assert r.code == 2 and r.err == [f"pyramid: error: --cluster {address}: connection refused: no Dask "
                                         f"scheduler listens on 127.0.0.1:{port}"], r.err
        assert r.seconds < 5, r.seconds
    with pytest.raises(UsageError, match="connection refused"):
        pyr.process_files(WORK, [str(tmp_path / "in" / "plate.####.exr")], template=str(tmp_path / "o.####.exr"),
                          backend="cpu", cluster=f"tcp://127.0.0.1:{port}", cluster_timeout=1)
    assert outputs(tmp_path / "out") == []


@pytest.fixture
def listener():
    """A TCP port that accepts connections and never says a word (not a Dask scheduler)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(8)
        yield s.getsockname()[1]


@pytest.mark.cli
@pytest.mark.parametrize("address, says", [
    ("garbage://x", "unknown address scheme garbage://"),
    ("tcp://host:port", "expected HOST:PORT"),
    ("tcp://a b:8786", "expected HOST:PORT"),
    ("tcp://127.0.0.1:70000", "port 70000 is not a TCP port"),
    ("tcp://no-such-host.invalid:8786", "unknown host no-such-host.invalid"),
    ("tls://127.0.0.1:{port}", "tls:// needs certificates: set distributed.comm.tls.ca-file"),
    ("wss://127.0.0.1:{port}", "wss:// needs certificates"),
    ("ucx://127.0.0.1:{port}", "ucx:// cannot be used on this machine (install distributed-ucxx)"),
    ("inproc://127.0.0.1/1/1", "no scheduler in this process listens there"),
    ("tcp://127.0.0.1:{port}", "no Dask scheduler answered in 1 s (--cluster-timeout)"),
    ("{tmp}/missing.json", "no such scheduler file after 1 s"),
    ("{tmp}/garbled.json", "not a Dask scheduler file (not JSON)"),
    ("local:0", "expected local:N with N ≥ 1"),
])
@pytest.mark.slow
def test_addresses_refused_in_one_line(tmp_path, listener, address, says, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.delenv("DASK_DISTRIBUTED__COMM__TLS__CA_FILE", raising=False)
    write_sequence(tmp_path / "in", 1, 2)
    (tmp_path / "garbled.json").write_text("{not json")
    address = address.format(port=listener, tmp=tmp_path)
    start = time.monotonic()
    r = CliRunner().invoke(main, [*map(str, blur(tmp_path, "out")), "--cluster", address, "--cluster-timeout", "1"])
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), (r.output, r.exception)  # no traceback
    assert r.output.count("\n") == 1 and r.output.startswith("pyramid: error: --cluster ") and says in r.output, \
        r.output
    assert time.monotonic() - start < 30  # the listener never answers: bounded by --cluster-timeout, not forever
    assert outputs(tmp_path / "out") == []


# ------------------------------------------------------------------ real scheduler and workers
@pytest.mark.slow
@pytest.mark.cli
def test_a_failing_chunk_reports_as_one_process(tmp_path, dask_cluster):
    """A corrupt frame: with --keep-going the cluster's report is the local run's, line for line; without, the
    counts are the files on disk, and the lines and the error those of a local run."""
    write_sequence(tmp_path / "in", 1, 12, size=(32, 32))
    (tmp_path / "in" / "plate.0001.exr").write_text("not an exr")
    procs = dask_cluster()
    one = pyramid(*blur(tmp_path, "one", "--keep-going"))
    assert one.code == 3 and one.err[-2] == "pyramid: 11 written, 0 up to date, 1 failed", one.err
    many = pyramid(*blur(tmp_path, "many", "--keep-going", "--cluster", procs.scheduler_file, "--chunk", "3"))
    assert many.code == 3, many.err
    assert one.out == sorted(one.out)  # a local run's lines are in job order too
    assert many.out == moved(one.out, "one", "many") and len(many.out) == 11  # every line, in job order
    assert many.err == one.err  # the summary and the error line, nothing of Dask's
    for name in outputs(tmp_path / "one"):
        assert (tmp_path / "many" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name

    first = pyramid(*blur(tmp_path, "first"))  # a local run stops at the corrupt frame
    stop = pyramid(*blur(tmp_path, "stop", "--cluster", procs.address.removeprefix("tcp://"), "--chunk", "3"))
    assert stop.code == first.code == 3 and only_ours(stop.err), stop.err
    on_disk = outputs(tmp_path / "stop")
    assert all(not name.startswith(".") for name in on_disk)
    assert stop.err == [f"pyramid: {len(on_disk)} written, 0 up to date, 1 failed", first.err[-1]]
    assert frames_of(stop.out) == frames_of(on_disk)  # a line for every file, in job order
    ours = {frames_of([line])[0]: line for line in one.out}
    assert stop.out == moved([ours[f] for f in frames_of(on_disk)], "one", "stop")


@pytest.mark.slow
@pytest.mark.cli
@pytest.mark.parametrize("command", [["blur", "--levels", "2"], ["mipmap", "--tile", "16"]])
def test_a_worker_killed_mid_chunk_loses_no_line(tmp_path, dask_cluster, command):
    """A worker dies half-way through a chunk (os._exit, after a temporary file): the chunk runs again elsewhere,
    and the run's outputs, lines and summary are a local run's."""
    write_sequence(tmp_path / "in", 1001, 1020, size=(32, 32))
    flag = tmp_path / "crashed"
    procs = dask_cluster({cluster.CRASH_VARIABLE: str(flag)})
    args = [*command, "--backend", "cpu", tmp_path / "in" / "plate.####.exr"]
    one = pyramid(*args, "-o", tmp_path / "one" / "soft.####.exr")
    many = pyramid(*args, "-o", tmp_path / "many" / "soft.####.exr", "--cluster", procs.address, "--chunk", "5", "-v")
    assert flag.exists()  # a worker did die half-way through a chunk
    assert one.code == many.code == 0, many.err
    assert one.out == sorted(one.out)
    assert many.out == moved(one.out, "one", "many")
    assert many.err[-1] == one.err[-1] == "pyramid: 20 written, 0 up to date, 0 failed"
    assert only_ours(many.err), many.err
    assert any(re.fullmatch(r"pyramid: cluster: worker tcp://127\.0\.0\.1:\d+ lost; chunk \d \(frames \d+-\d+\) "
                            r"rescheduled.*", line) for line in many.err), many.err
    names = outputs(tmp_path / "one")
    assert len(names) == 20 and outputs(tmp_path / "many") == names  # no temporary file left, nothing extra
    for name in names:
        assert (tmp_path / "many" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name


def run_and_kill(tmp_path, args: list, kill) -> SimpleNamespace:
    """Start the command, ``kill()`` once its first output is on disk, and wait for it (never forever)."""
    start = time.monotonic()
    p = subprocess.Popen([sys.executable, "-m", "pyramid_cli.cli", *map(str, args)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        while not [n for n in outputs(tmp_path / "many") if not n.startswith(".")]:
            assert p.poll() is None and time.monotonic() - start < HANG, "finished or hung before its first output"
            time.sleep(0.02)
        kill()
        out, err = p.communicate(timeout=HANG)
    finally:
        p.kill()
        p.wait()
    return SimpleNamespace(code=p.returncode, out=out.splitlines(), err=err.splitlines(),
                           seconds=time.monotonic() - start)


def assert_frames_accounted(r, frames: list[int], reason: str) -> None:
    """Written frames have their lines and files; the rest are named in one error line; the summary adds up."""
    written = frames_of(r.out)
    assert written == sorted(written)
    missing = [f for f in frames if f not in written]
    assert missing, "the run was not cut short"
    assert only_ours(r.err), r.err
    assert r.err[-2] == f"pyramid: {len(written)} written, 0 up to date, {len(missing)} failed", r.err
    assert re.fullmatch(rf"pyramid: error: cluster tcp://127\.0\.0\.1:\d+: {reason}; {not_done(missing)} not done",
                        r.err[-1]), r.err[-1]


@pytest.mark.slow
@pytest.mark.cli
def test_the_scheduler_killed_is_one_line_naming_the_frames_not_done(tmp_path, dask_cluster):
    write_sequence(tmp_path / "in", 1, 12, size=(32, 32))
    procs = dask_cluster({cluster.SLOW_VARIABLE: "1"})
    r = run_and_kill(tmp_path, blur(tmp_path, "many", "--cluster", procs.address, "--chunk", "2"),
                     procs.kill_scheduler)
    procs.kill_workers()
    assert r.code == 6, r.err
    assert_frames_accounted(r, list(range(1, 13)), "lost the scheduler")
    for f in frames_of(r.out):
        assert (tmp_path / "many" / f"soft.{f:04d}.exr").exists()


@pytest.mark.slow
@pytest.mark.cli
def test_every_worker_lost_fails_after_the_cluster_timeout(tmp_path, dask_cluster):
    write_sequence(tmp_path / "in", 1, 12, size=(32, 32))
    procs = dask_cluster({cluster.SLOW_VARIABLE: "1"})
    r = run_and_kill(tmp_path, blur(tmp_path, "many", "--cluster", procs.address, "--chunk", "2",
                                    "--cluster-timeout", "2"), procs.kill_workers)
    assert r.code == 6, r.err
    assert_frames_accounted(r, list(range(1, 13)), r"no worker connected for 2 s \(--cluster-timeout\)")
    assert frames_of(outputs(tmp_path / "many")) == frames_of(r.out)  # no temporary file left by the dead
    assert r.seconds < HANG


@pytest.mark.slow
@pytest.mark.cli
def test_a_chunk_the_cluster_gives_up_on_counts_what_it_wrote(tmp_path, dask_cluster):
    """The scheduler allows no worker death: the chunks on the worker that dies fail, and the frames written before
    it died count as written, with their lines."""
    write_sequence(tmp_path / "in", 1, 12, size=(32, 32))
    procs = dask_cluster({cluster.CRASH_VARIABLE: str(tmp_path / "crashed"),
                          "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"})
    r = pyramid(*blur(tmp_path, "many", "--cluster", procs.address, "--chunk", "4", "--keep-going"))
    assert (tmp_path / "crashed").exists() and r.code == 6, r.err
    written = frames_of(r.out)
    assert written == frames_of(outputs(tmp_path / "many")) and len(written) >= 2, (r.out, r.err)  # half a chunk
    missing = [f for f in range(1, 13) if f not in written]
    errors = [line for line in r.err if line.startswith("pyramid: error:")]
    assert only_ours(r.err) and r.err[-1 - len(errors)] == \
        f"pyramid: {len(written)} written, 0 up to date, {len(missing)} failed", r.err
    named = []
    for line in errors:
        m = re.fullmatch(r"pyramid: error: cluster tcp://\S+: chunk \d \((frames [\d,:-]+)\): its workers died running "
                         r"it more often than the scheduler allows \(distributed.scheduler.allowed-failures\); "
                         r"(frames? [\d,:-]+) not done", line)
        assert m, line
        named.append(m.group(2))
    assert sorted(f for text in named for f in expand(text)) == missing


@pytest.mark.slow
def test_local_cluster_matches_one_process_and_survives_a_killed_worker(tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")
    write_sequence(tmp_path / "in", 1001, 1030, size=(32, 32))
    pattern = str(tmp_path / "in" / "plate.####.exr")
    assert pyr.process_files(WORK, [pattern], template=str(tmp_path / "one" / "soft.####.exr"),
                             backend="cpu").exit_code == 0

    flag = tmp_path / "crashed"
    monkeypatch.setenv(cluster.CRASH_VARIABLE, str(flag))  # inherited by the worker processes
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None) as local, distributed.Client(local) as client:
        code = pyr.process_files(WORK, [pattern], template=str(tmp_path / "many" / "soft.####.exr"),
                                 backend="cpu", cluster=client, chunk=5).exit_code
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
    r = pyramid("blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "plate.####.exr",
                "-o", tmp_path / "out" / "soft.####.exr", "--cluster", "local:2", "--chunk", "3", "--keep-going")
    assert r.code == 3, r.err
    assert "plate.0005.exr" in r.err[-1] and r.err[-2] == "pyramid: 7 written, 0 up to date, 1 failed"
    assert only_ours(r.err), r.err
    assert frames_of(r.out) == [1, 2, 3, 4, 6, 7, 8]
    assert len(outputs(tmp_path / "out")) == 7


def test_api_takes_frames_and_shards(tmp_path):
    write_sequence(tmp_path / "in", 1, 6)
    kw = {"template": str(tmp_path / "out" / "o.{frame}.exr"), "backend": "cpu", "frames": "1-6x1"}
    assert pyr.process_files(WORK, [str(tmp_path / "in" / "plate.####.exr")], shard="2/3", **kw).exit_code == 0
    assert outputs(tmp_path / "out") == ["o.3.exr", "o.4.exr"]


def test_a_worker_keeps_its_chunk_within_its_own_memory_budget(tmp_path, monkeypatch):
    """A worker runs its chunk as a local batch does (run.local.run_in_budget): with its budget (its container's
    limits; here made small) a picture too large to be held beside the others streams alone, and the files are the
    ones a run with room writes."""
    distributed = pytest.importorskip("distributed")
    from pyramid_cli.run import budget

    rng = np.random.default_rng(11)
    for k, shape in enumerate([(8, 6, 3), (240, 320, 3), (10, 12, 3)]):
        pyr.write_image(tmp_path / "in" / f"p{k}.exr", rng.random(shape).astype(np.float32), pixel_type="float")
    inputs = sorted(str(p) for p in (tmp_path / "in").glob("*.exr"))
    assert pyr.process_files(WORK, inputs, template=str(tmp_path / "one" / "{stem}.exr"), backend="cpu").exit_code == 0
    monkeypatch.setattr(budget, "default_budget", lambda root="/": budget.Budget(1 << 20))  # the workers run here
    said = []
    monkeypatch.setattr(budget.Budget, "describe", lambda self: said.append(self.size) or "1.0 MiB (test)")
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1,
                                  dashboard_address=None) as local, distributed.Client(local) as client:
        report = pyr.process_files(WORK, inputs, template=str(tmp_path / "many" / "{stem}.exr"), backend="cpu",
                                   cluster=client, chunk=3, quiet=False)
    assert report.exit_code == 0 and len(report.done) == 3
    assert said and set(said) == {1 << 20}  # the middle picture ran alone, in the worker's budget
    for name in outputs(tmp_path / "one"):
        assert (tmp_path / "many" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name
