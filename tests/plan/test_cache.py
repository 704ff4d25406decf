"""Plans cached in the process and on disk (pyramid_cli.plan.cache): the same plan as a fresh one, recomputed
whenever an entry is not exactly this plan's, and harmless where the cache folder cannot be written."""

from __future__ import annotations

import dataclasses
import json
from fractions import Fraction

import numpy as np
import pytest

from helpers.plans import random_image
from pyramid_cli.core import cache as disk
from pyramid_cli.core.cache import HOME_ENV
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.jobs.texture import TextureLevels
from pyramid_cli.jobs.work import Blend, Blur, Collapse, Fill, Filter, Laplacian, Levels, blur_work
from pyramid_cli.plan import cache, check, cost, lower
from pyramid_cli.plan.model import Plan


@pytest.fixture(autouse=True)
def cache_home(tmp_path, monkeypatch):
    """Every test its own cache folder and an empty memo."""
    monkeypatch.setenv(HOME_ENV, str(tmp_path / "cache"))
    cache.clear_memo()
    yield tmp_path / "cache"
    cache.clear_memo()


WORKS = {
    "apply chain": (Filter(expr=parse("box\\ *v bartlett"), border="mirror"), [(13, 11)]),
    "written mask": (Filter(expr=parse("1/4 [1 1; 1 1] *v g")), [(9, 8)]),
    "blur levels": (Blur(levels=2), [(19, 23)]),
    "blur quasi wrap": (Blur(levels=1, quasi=True, border="wrap"), [(16, 12)]),
    "sigma blur": (blur_work(sigma=2.5), [(21, 17)]),
    "levels": (Levels(levels=3), [(17, 10)]),
    "laplacian": (Laplacian(levels=2), [(12, 15)]),
    "collapse": (Collapse(bands=3), [(12, 15), (6, 8), (3, 4)]),
    "mipmap odd": (TextureLevels(), [(13, 7)]),
    "mipmap resize": (TextureLevels(resize=True), [(5, 6)]),
    "mipmap up": (TextureLevels(rounding="up"), [(9, 6)]),
    "fill": (Fill(levels=2), [(10, 9)]),
    "blend": (Blend(levels=2), [(10, 9)] * 3),
}


def same_types(a, b) -> bool:
    """Equal and of the same types all the way down (Fraction(1) == 1 and (1, 2) != [1, 2] hide nothing)."""
    if type(a) is not type(b):
        return False
    if dataclasses.is_dataclass(a):
        return all(same_types(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same_types(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return list(a) == list(b) and all(same_types(a[k], b[k]) for k in a)
    return a == b


def fresh(work, sizes, strategy) -> Plan | None:
    return work.make_plan(tuple(sizes), strategy)


@pytest.mark.parametrize("name", list(WORKS))
@pytest.mark.parametrize("strategy", ["fused", "cost"])
def test_a_plan_read_back_is_the_plan_made_fresh(name, strategy, monkeypatch):
    work, sizes = WORKS[name]
    first = work.plan(sizes, strategy)            # made, written
    cache.clear_memo()
    monkeypatch.setattr(type(work), "make_plan", lambda *a: pytest.fail("planned again instead of read back"))
    read = work.plan(sizes, strategy)              # read from disk
    monkeypatch.undo()
    want = fresh(work, sizes, strategy)
    assert read is not first and read == want and same_types(read, want)
    check(read)
    rng = np.random.default_rng(3)
    images = [rng.random(want.images[i].size + (2,)) for i in want.inputs]
    for got, ref in zip(emulate.run_outputs(read, images), emulate.run_outputs(want, images), strict=True):
        assert np.array_equal(got, ref)


def test_nothing_to_compute_is_cached_too(monkeypatch):
    work = Levels()
    assert work.plan([(1, 1)]) is None
    cache.clear_memo()
    monkeypatch.setattr(Levels, "make_plan", lambda *a: pytest.fail("planned again"))
    assert work.plan([(1, 1)]) is None


def test_a_batch_of_one_size_plans_once(monkeypatch):
    calls = []
    made = Blur.make_plan
    monkeypatch.setattr(Blur, "make_plan", lambda self, *a: calls.append(a) or made(self, *a))
    plans = [Blur(levels=2).plan([(30, 40, 3)], "fused") for _ in range(50)]
    assert len(calls) == 1 and all(p is plans[0] for p in plans)


def entry(work, sizes, strategy, home):
    return home / cache.FOLDER / cache.entry_name(cache.plan_key(work, sizes, strategy))


@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty", "not a plan", "wrong types", "directory"])
def test_a_damaged_entry_is_recomputed_and_rewritten(damage, cache_home):
    work, sizes = WORKS["mipmap odd"]
    want = work.plan(sizes, "fused")
    path = entry(work, sizes, "fused", cache_home)
    data = path.read_bytes()
    if damage == "directory":
        path.unlink()
        path.mkdir()
    else:
        doc = json.loads(data)
        doc["plan"]["passes"][0][2] = "seven"
        path.write_bytes({"truncated": data[:len(data) // 2], "garbage": b"\xff\x00 plan", "empty": b"",
                          "not a plan": b'{"key": 1}', "wrong types": json.dumps(doc).encode()}[damage])
    cache.clear_memo()
    got = work.plan(sizes, "fused")
    assert got == want and same_types(got, want)
    if damage != "directory":
        assert path.read_bytes() == data  # rewritten whole


def test_an_entry_of_another_version_is_not_read(cache_home, monkeypatch):
    work, sizes = WORKS["blur levels"]
    want = work.plan(sizes, "fused")
    path = entry(work, sizes, "fused", cache_home)
    doc = json.loads(path.read_bytes())
    other = Blur(levels=5).make_plan(((64, 64),), "fused")   # another plan, under this key's name
    path.write_text(json.dumps({"key": doc["key"].replace(f"'{cache.__version__}'", "'0.0.1'"),
                                **cache.encode(other)}))
    cache.clear_memo()
    assert work.plan(sizes, "fused") == want
    assert json.loads(path.read_bytes())["key"] == doc["key"]


def test_every_setting_that_changes_a_plan_changes_its_key():
    key = cache.plan_key
    base = key(Blur(levels=2), [(8, 8)], "cost")
    assert len({base, key(Blur(levels=3), [(8, 8)], "cost"), key(Blur(levels=2, border="wrap"), [(8, 8)], "cost"),
                key(Blur(levels=2), [(8, 9)], "cost"), key(Blur(levels=2), [(8, 8)], "fused"),
                key(Levels(levels=2), [(8, 8)], "cost"), key(TextureLevels(levels=2), [(8, 8)], "cost")}) == 7
    # where the expression was written in the command line is not part of it; its channels are not either
    assert key(Filter(expr=parse("box *v g")), [(8, 8)], "cost") == key(Filter(expr=parse("  box *v g")),
                                                                         [(8, 8, 3)], "cost")


def test_the_cost_model_is_part_of_the_key(monkeypatch):
    work, sizes = Filter(expr=parse("gauss7")), [(64, 64)]
    calibrated = work.plan(sizes, "cost")
    slow_passes = dataclasses.replace(cost.model(), pass_s=1.0)    # every pass costs a second: fuse
    monkeypatch.setattr(cost, "model", lambda: slow_passes)
    lower.choose_recipe.cache_clear()  # the planner's own in-process caches are keyed without the model
    lower.plan.cache_clear()
    try:
        fused = work.plan(sizes, "cost")
    finally:
        lower.choose_recipe.cache_clear()
        lower.plan.cache_clear()
    assert len(calibrated.passes) > 1 and len(fused.passes) == 1


def test_plans_that_weigh_no_recipe_never_load_the_cost_model(monkeypatch):
    monkeypatch.setattr(cost, "model", lambda: pytest.fail("the cost model was consulted"))
    for strategy in cache.MODEL_FREE:
        assert Blur(levels=2).plan([(16, 16)], strategy) is not None


def test_an_unwritable_cache_folder_costs_only_the_speed_up(tmp_path, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(HOME_ENV, str(blocker / "cache"))
    work, sizes = WORKS["fill"]
    assert work.plan(sizes, "fused") == fresh(work, sizes, "fused")
    assert not (blocker / "cache").exists()


def test_an_entry_holds_exact_fractions_and_no_code(cache_home):
    work, sizes = WORKS["mipmap odd"]
    work.plan(sizes, "fused")
    doc = json.loads(entry(work, sizes, "fused", cache_home).read_bytes())
    assert doc["key"] == cache.plan_key(work, sizes, "fused")
    assert all(isinstance(n, int) and isinstance(d, int) and d > 0 for n, d in doc["plan"]["fractions"])
    assert Fraction(*doc["plan"]["fractions"][0])


def test_a_plan_the_entry_cannot_hold_is_not_written(cache_home):
    p = Blur(levels=1).make_plan(((8, 8),), "fused")
    odd = dataclasses.replace(p, paper_fetches=Fraction(3, 2))
    assert not cache.store("k", odd) and not (cache_home / cache.FOLDER / cache.entry_name("k")).exists()


def test_the_folder_keeps_the_most_recently_used_entries(cache_home):
    for n in range(6):
        assert cache.store(f"key {n}", None)
    cache.load("key 0")  # used: kept
    cache.prune(keep=3)
    names = {p.name for p in (cache_home / cache.FOLDER).iterdir()}
    assert cache.entry_name("key 0") in names and len(names) == 3
    assert disk.read(cache.FOLDER, cache.entry_name("key 1")) is None


@pytest.mark.slow
@pytest.mark.parametrize("name", ["blur levels", "mipmap odd", "fill"])
def test_the_cpu_executor_runs_a_plan_read_back_to_the_same_bytes(name, cpu_executor):
    work, sizes = WORKS[name]
    made = work.plan(sizes, "fused")
    cache.clear_memo()
    read = work.plan(sizes, "fused")
    assert read is not made
    images = [random_image(made.images[i].size, 3, seed=i) for i in made.inputs]
    for a, b in zip(cpu_executor.run_outputs(made, images, np.float32),
                    cpu_executor.run_outputs(read, images, np.float32), strict=True):
        assert a.tobytes() == b.tobytes()


@dataclasses.dataclass(frozen=True, kw_only=True)
class MyBlur(Blur):
    """A caller's own job: its code can change under the same name and fields."""


def test_a_callers_own_job_is_kept_in_the_process_only(cache_home):
    work = MyBlur(levels=1)
    first = work.plan([(8, 8)], "fused")
    assert work.plan([(8, 8)], "fused") is first
    assert not (cache_home / cache.FOLDER).exists()
