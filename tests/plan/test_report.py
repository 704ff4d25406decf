"""What `pyramid plan` prints (pyramid_cli.plan.report)."""

from pyramid_cli.core.parse import parse
from pyramid_cli.plan import plan, report


def test_json_and_text_agree_on_the_passes():
    p = plan(parse("box4 *v g"), (8, 6))
    info = report.to_json(p)
    assert {"expression", "input", "output", "passes", "fetches", "estimate_s"} <= set(info)
    assert len(info["passes"]) == len(p.passes)
    text = report.render(p)
    assert text.startswith("plan ") and f"{len(p.passes)} pass(es)" in text
