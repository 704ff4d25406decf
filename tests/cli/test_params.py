"""The options and parameter types the commands share (pyramid_cli.cli.params): one spelling everywhere."""

import click
import numpy as np
import pytest
from click.testing import CliRunner

from helpers.cli import invoke
from helpers.images import write
from pyramid_cli.cli import main
from pyramid_cli.cli.params import EXPR, border_option, choice, io_options
from pyramid_cli.core.expr import Expr


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("params")
    write(d / "good.exr", np.random.default_rng(0).random((16, 16, 3)))
    return d


@pytest.mark.cli
def test_bad_expression_exits_2_with_a_caret():
    r = invoke("explain", "bartlet ⊗ g")
    assert r.exit_code == 2
    assert "did you mean 'bartlett'?" in r.output
    assert "  ^^^^^^^" in r.output


def test_bad_expression_and_bad_option_exit_2(files, tmp_path):
    r = CliRunner().invoke(main, ["apply", "quadratc *v g", str(files / "good.exr"), str(tmp_path / "o.exr")])
    assert r.exit_code == 2 and "did you mean 'quadratic'" in r.output
    r = CliRunner().invoke(main, ["blur", "--levels", "0", str(files / "good.exr"), str(tmp_path / "o.exr")])
    assert r.exit_code == 2


def test_expression_type_parses_strings_and_passes_parsed_expressions_through():
    e = EXPR.convert("quadratic *v g", None, None)
    assert isinstance(e, Expr)
    assert EXPR.convert(e, None, None) is e


def test_choice_offers_the_values_in_order():
    assert list(choice(("clamp", "wrap")).choices) == ["clamp", "wrap"]


def _command(seen: dict, *decorators):
    """A click command with ``decorators`` that keeps the options it was called with in ``seen``."""
    def body(**opts):
        seen.update(opts)

    for d in reversed(decorators):
        body = d(body)
    return click.command()(body)


def test_io_options_defaults_and_border_default():
    opts = {}
    r = invoke(command=_command(opts, border_option, io_options))
    assert r.exit_code == 0, r.output
    assert opts["backend"] == "auto" and opts["border"] == "clamp" and opts["nan_policy"] == "keep"
    assert opts["colorspace"] == "auto" and opts["alpha"] == "auto" and opts["precision"] == "float"
    assert not opts["force"] and not opts["quiet"] and not opts["verbose"] and opts["threads"] is None


def test_border_option_refuses_an_unknown_mode():
    r = invoke("--border", "reflect", command=_command({}, border_option))
    assert r.exit_code == 2 and "reflect" in r.output
