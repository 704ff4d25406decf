"""The plan's data contract (pyramid_cli.plan.model): what passes read and write, checked."""

from pyramid_cli.core.parse import parse
from pyramid_cli.plan import check, plan


def test_a_planned_chain_checks_and_reads_its_input():
    p = plan(parse("doosabin *^ (box4 *v g)"), (17, 13))
    check(p)
    assert p.images[0].size == (17, 13) and p.output.size == (18, 14)  # ⌈17/2⌉·2 × ⌈13/2⌉·2
    assert all(ps.target < len(p.images) for ps in p.passes)
    assert list(p.inputs) == [0] and p.outputs[-1] == p.passes[-1].target and p.border == "clamp"



def test_releases_name_each_image_once_after_its_last_read():
    """Plan.releases: every image a pass reads and the plan does not return is released once, at the pass that
    reads it last (what every executor frees or reuses); inputs too, returned images never."""
    from pyramid_cli.workflows.pyramids import levels_plan

    for p in (plan(parse("doosabin *^ (box4 *v g)"), (17, 13)), levels_plan((37, 29), 3)):
        released = p.releases()
        assert len(released) == len(p.passes)
        flat = [s for done in released for s in done]
        assert len(flat) == len(set(flat)) and not set(flat) & set(p.outputs)
        read = {s for ps in p.passes for s in ps.sources()}
        assert set(flat) == read - set(p.outputs) and 0 in flat
        for i, done in enumerate(released):
            for s in done:
                assert s in p.passes[i].sources() and all(s not in ps.sources() for ps in p.passes[i + 1:])


def test_reads_moved_by_whole_periods_are_worked_out_once_and_exact():
    """Pass.reads remembers a rectangle's reads by its shape and moves them by whole periods: every answer equals
    the bounds worked out afresh (``_reads``), for phased passes (periods 2 and 4) at every offset and size."""
    import random

    rng = random.Random(7)
    for text in ("gauss5", "box4 *v g", "fourpoint *^ (cubic *v g)", "cubic *^ (cubic *v g)"):
        for ps in plan(parse(text), (37, 29)).passes:
            if not hasattr(ps, "phases"):
                continue
            for _ in range(200):
                r0, c0 = rng.randrange(-9, 40), rng.randrange(-9, 40)
                rows, cols = (r0, r0 + rng.randrange(1, 20)), (c0, c0 + rng.randrange(1, 20))
                assert ps.reads(rows, cols) == ps._reads(rows, cols), (text, ps.label, rows, cols)
            assert len(ps.__dict__["_reads_memo"]) <= 200
