"""The plan's data contract (pyramid_cli.plan.model): what passes read and write, checked."""

from pyramid_cli.core.parse import parse
from pyramid_cli.plan import check, plan


def test_a_planned_chain_checks_and_reads_its_input():
    p = plan(parse("doosabin *^ (box4 *v g)"), (17, 13))
    check(p)
    assert p.images[0].size == (17, 13) and p.output.size == (18, 14)  # ⌈17/2⌉·2 × ⌈13/2⌉·2
    assert all(ps.target < len(p.images) for ps in p.passes)
    assert list(p.inputs) == [0] and p.outputs[-1] == p.passes[-1].target and p.border == "clamp"

