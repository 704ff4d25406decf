"""A cluster worker's side (pyramid_cli.run.cluster.worker): its session's settings, and the lines and outputs a
chunk run again finds on disk. Chunks on real workers: tests/system/test_dask.py."""

import os
import time

import numpy as np

import pyramid_cli as pyr
from pyramid_cli.run import batch
from pyramid_cli.run.cluster import worker


def test_session_specs_name_their_own_plugin():
    assert worker.SessionSpec().plugin_name == f"{worker.PLUGIN_NAME}-auto-float-0"
    assert worker.SessionSpec("cpu", "half", 4).plugin_name == f"{worker.PLUGIN_NAME}-cpu-half-4"


def test_no_bar_counts_nothing_and_passes_errors_on():
    with worker.NoBar(10) as bar:
        bar.update(3)
    assert bar.__exit__(ValueError, ValueError(), None) is False


def test_written_since_needs_a_fresh_output_written_after_the_start(tmp_path):
    src, out = tmp_path / "in.exr", tmp_path / "out.exr"
    src.write_bytes(b"in")
    job = batch.Job(str(src), str(out))
    assert not worker.written_since(job, time.time())  # no output yet
    out.write_bytes(b"out")
    assert worker.written_since(job, os.path.getmtime(out) - 1)
    assert not worker.written_since(job, os.path.getmtime(out) + 1)  # there before the run began
    later = os.path.getmtime(out) + 5
    os.utime(src, (later, later))  # the input changed after: not up to date
    assert not worker.written_since(job, 0.0)


def test_line_from_disk_is_the_line_a_local_run_prints(tmp_path):
    out = tmp_path / "soft.0001.exr"
    pyr.write_image(out, np.zeros((6, 10, 3), np.float32))
    job = batch.Job("in.exr", str(out))
    assert worker.line_from_disk(job, pyr.Blur(levels=2), None, "cpu") == f"wrote {out} (10×6, cpu)"
    assert worker.line_from_disk(job, pyr.Blur(levels=2), 16, "gl") == f"wrote {out} (10×6, 4 MIP levels, gl)"
