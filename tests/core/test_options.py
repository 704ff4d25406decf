"""The option vocabularies the CLI and the API share (pyramid_cli.core.options)."""

import pytest

from pyramid_cli.core import options


def test_check_returns_a_valid_value_and_names_the_choices_otherwise():
    assert options.check("--border", "wrap", options.BORDERS) == "wrap"
    with pytest.raises(ValueError, match="--border must be one of clamp.*not 'warp'"):
        options.check("--border", "warp", options.BORDERS)


def test_vocabularies():
    assert set(options.BORDERS) == {"clamp", "mirror", "wrap", "zero"}
    assert options.BACKENDS[0] == "auto" and set(options.BACKEND_HELP) >= set(options.BACKENDS) - {"auto"}
    assert options.COLORSPACES == ("auto", *options.ENCODINGS)
