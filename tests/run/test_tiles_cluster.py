"""``pyramid tiles --cluster`` (issue 27): one picture's tiles written by Dask workers, byte for byte a local run's."""

from __future__ import annotations

import dataclasses
import json
import logging
import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.images import write
from helpers.tilesets import outputs
from pyramid_cli import api as pyr
from pyramid_cli.cli import main
from pyramid_cli.core.errors import UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Levels
from pyramid_cli.run.tiles_cluster import CRASH_VARIABLE, split

SIZE = (93, 71)  # odd at every level; 12 rows of 8-pixel tiles
TILE = 8


# ------------------------------------------------------------------ the arithmetic the split rests on
@pytest.mark.parametrize("size, analysis, border", [((37, 53), "quadratic", "clamp"), ((101, 29), "cubic", "mirror"),
                                                    ((9, 300), "box", "zero")])
def test_levels_from_level_m_are_the_one_plans_floats(size, analysis, border):
    """Levels m+1.. planned from level m are bit for bit those of the one plan, for every m (the CPU executor)."""
    session = Session("cpu")
    x = np.random.default_rng(3).random(size + (3,), dtype=np.float32)
    count = 1 + max(int(np.ceil(np.log2(max(size)))), 0)
    whole = session.run(Levels(levels=count - 1, analysis=analysis, border=border), [x], np.float32)[1:]
    for m in range(1, count - 1):
        first = session.run(Levels(levels=m, analysis=analysis, border=border), [x], np.float32)[1:]
        rest = session.run(Levels(levels=count - 1 - m, analysis=analysis, border=border),
                           [np.ascontiguousarray(first[-1])], np.float32)[1:]
        for k, (a, b) in enumerate(zip(whole, first + rest, strict=True)):
            assert a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32)), (m, k + 1)


def test_blocks_are_as_large_as_two_tasks_per_worker_allow():
    assert split(12, 8, 2) == 1 and split(64, 10, 2) == 4 and split(64, 3, 2) == 2  # at most the coarsest level
    assert split(12, 8, 8) == 1 and split(12, 1, 8) == 0  # level 1 made by the blocks, when there is one
    assert split(12, 8, 1) == 3 and split(1, 5, 4) == 4  # one row of tiles: one task makes every level
    assert split(12, 8, 2, chunk=3) == 2 and split(12, 2, 2, chunk=64) == 1 and split(9, 5, 2, chunk=1) == 0


# ------------------------------------------------------------------ refused before a cluster is reached
@pytest.fixture(scope="module")
def picture(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("tiles-cluster")
    rng = np.random.default_rng(5)
    y, x = np.mgrid[0:SIZE[0], 0:SIZE[1]]
    px = 0.5 + 0.4 * np.sin(x * 0.7 + y * 0.13)[..., None] * np.array([1, 0.6, -0.8]) + rng.normal(0, 0.05, SIZE + (3,))
    write(folder / "in.png", np.clip(px, 0, 1).astype(np.float32), "png")
    return folder / "in.png"


@pytest.mark.parametrize("args, says", [
    (["x.tif"], "a tiff tile set is one file written in order"),
    (["--border", "wrap", "x.dzi"], "--border wrap reads every level whole"),
    (["--dither", "x.dzi"], "--dither's pattern follows the bands"),
    (["--backend", "reference", "x.dzi"], "--cluster needs a plan executor"),
])
def test_what_cannot_be_split_is_refused_in_one_line(picture, tmp_path, args, says):
    r = CliRunner().invoke(main, ["tiles", "--cluster", "local:2", str(picture), *args[:-1], str(tmp_path / args[-1])])
    assert r.exit_code == 2 and says in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert os.listdir(tmp_path) == []


def test_cluster_options_need_cluster_and_arrays_stay_local(picture, tmp_path):
    r = CliRunner().invoke(main, ["tiles", "--chunk", "2", str(picture), str(tmp_path / "x.dzi")])
    assert r.exit_code == 2 and "are for --cluster runs" in r.output
    with pytest.raises(UsageError, match="an array is written in this process"):
        pyr.tiles(np.zeros((4, 4, 3), np.float32), tmp_path / "x.dzi", cluster="local:1")


# ------------------------------------------------------------------ on a cluster
@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """One worker process (a second costs seconds to start); a task whose worker dies is tried once more
    (allowed-failures 1). The workers crash as :data:`CRASH_VARIABLE` says, through a flag file the tests create
    (it is read when a task runs)."""
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    flags = tmp_path_factory.mktemp("flags")
    os.environ[CRASH_VARIABLE] = str(flags / "crash")
    try:
        with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
                distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1, host="127.0.0.1",
                                         dashboard_address=None, silence_logs=logging.CRITICAL) as cluster, \
                distributed.Client(cluster, set_as_default=False) as c:
            c.flags = flags
            yield c
    finally:
        del os.environ[CRASH_VARIABLE]


@pytest.fixture(scope="module")
def local(picture, tmp_path_factory):
    """The local run's tile set of each case, by name."""
    folder = tmp_path_factory.mktemp("local")

    def make(name: str, **kw) -> dict[str, bytes]:
        out = folder / json.dumps(kw, sort_keys=True).replace("/", "_") / name
        if not out.exists():
            out.parent.mkdir()
            pyr.tiles(picture, out, backend="cpu", **kw)
        return outputs(out)
    return make


CASES = {
    "dz": ("scan.dzi", {"tile_size": TILE}),                                   # JPEG tiles, overlap 1
    "dz-png-overlap": ("scan.dzi", {"tile_size": 5, "overlap": 2, "format": "png", "analysis": "cubic"}),
    "iiif3": ("iiif", {"layout": "iiif3", "tile_size": TILE}),
    "ome-zarr": ("slide.ome.zarr", {"tile_size": TILE, "border": "mirror"}),
}


@pytest.mark.slow
@pytest.mark.parametrize("case, chunk", [("dz", 4), ("dz-png-overlap", 2), ("iiif3", None), ("ome-zarr", 1)])
def test_the_tile_set_is_byte_for_byte_the_local_runs(client, local, picture, tmp_path, case, chunk):
    """Every file of the tree, at an odd size, in several tasks (levels 0..m each, then m+1.. from level m; chunk 1:
    m = 0, the last task makes every level below the input)."""
    name, kw = CASES[case]
    report = pyr.tiles(picture, tmp_path / name, backend="cpu", cluster=client, chunk=chunk, **kw)
    assert report["cluster"]["tasks"] > 2 and report["cluster"]["workers"] == 1
    got, want = outputs(tmp_path / name), local(name, **kw)
    assert sorted(got) == sorted(want) and len(got) > 20
    assert [k for k in want if got[k] != want[k]] == []
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]  # the staging folder is gone


@pytest.mark.slow
@pytest.mark.cli
def test_cli_on_a_scheduler_address_writes_the_local_runs_deep_zoom(client, picture, local, tmp_path):
    """The module's cluster by its address, as a farm gives it (a new local:N would cost seconds to start)."""
    address = client.scheduler.address
    r = CliRunner().invoke(main, ["tiles", "--tile-size", str(TILE), "--backend", "cpu", "--cluster", address,
                                  "--json", str(picture), str(tmp_path / "scan.dzi")])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["cluster"]["address"] == address and doc["cluster"]["workers"] == 1
    assert doc["path"] == str(tmp_path / "scan.dzi") and doc["cluster"]["tasks"] > 2
    assert outputs(tmp_path / "scan.dzi") == local("scan.dzi", tile_size=TILE)


@pytest.mark.slow
def test_a_worker_lost_mid_task_is_retried_and_the_bytes_are_the_same(client, local, picture, tmp_path):
    """The first task to finish kills its worker after writing its tiles: Dask runs it again elsewhere, which
    writes the same files again."""
    (client.flags / "crash").write_text("once")
    try:
        pyr.tiles(picture, tmp_path / "scan.dzi", backend="cpu", cluster=client, tile_size=TILE)
    finally:
        (client.flags / "crash").unlink(missing_ok=True)
    assert (client.flags / "crash.done").exists()  # it did crash
    assert outputs(tmp_path / "scan.dzi") == local("scan.dzi", tile_size=TILE)


@pytest.mark.slow
def test_a_task_that_keeps_killing_its_workers_is_exit_6_and_the_previous_output_stays(client, picture, tmp_path):
    from pyramid_cli.run.cluster import ClusterError

    out = tmp_path / "scan.dzi"
    pyr.tiles(picture, out, backend="cpu", tile_size=TILE, format="png")
    before = outputs(out)
    (client.flags / "crash").write_text("always")
    try:
        with pytest.raises(ClusterError, match="killed its workers more often than the scheduler allows") as e:
            pyr.tiles(picture, out, backend="cpu", cluster=client, tile_size=TILE)
    finally:
        (client.flags / "crash").unlink(missing_ok=True)
    assert e.value.exit_code == 6 and "\n" not in str(e.value)
    assert outputs(out) == before
    client.run(lambda: None)  # the workers are back before the next test
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]


def test_dataclass_of_a_task_travels(picture):
    """What a task is given pickles (Dask sends it to the workers)."""
    import pickle

    from pyramid_cli.imageio.tilesets import TileOptions
    from pyramid_cli.run.settings import ReadOptions
    from pyramid_cli.run.tiles_cluster import PartJob

    job = PartJob(str(picture), "x.dzi", "dz", TileOptions(8), ReadOptions(), "quadratic", "clamp", "/tmp", 2, 3, 4)
    assert pickle.loads(pickle.dumps(job)) == job and dataclasses.replace(job, block=-1).block == -1
