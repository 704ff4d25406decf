"""What `pyramid explain` says about an expression (pyramid_cli.run.explain)."""

import pytest

from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.parse import parse
from pyramid_cli.run import explain


def test_describe_and_render_name_the_filter():
    info = explain.describe(parse("box4 *v g"))
    assert info["ascii"] == "box4 *v g" and info["stride"] == 2
    text = explain.render(info)
    assert "box4 *v g" in text and "analysis" in text


def test_plots_are_png_svg_or_pdf():
    assert explain.check_plot_path("powers.SVG") == "svg"
    with pytest.raises(UsageError, match="not .jpg"):
        explain.check_plot_path("powers.jpg")
