"""The error types and their one table of exit codes (pyramid_cli.core.errors)."""

import pytest

from pyramid_cli.core import errors


def test_exit_codes_are_distinct_and_documented():
    codes = [code for code, _ in errors.EXIT_CODES.values()]
    assert len(set(codes)) == len(codes)
    assert errors.exit_code("ok") == 0 and errors.exit_code("usage") == 2 and errors.exit_code("interrupted") == 130
    assert all(why for _, why in errors.EXIT_CODES.values())


@pytest.mark.parametrize("make, name, value_error", [
    (errors.UsageError, "usage", True), (lambda m: errors.ExpressionError(m, "box *", 4), "usage", True),
    (errors.InputError, "input", False), (errors.OutputError, "output", False), (errors.DataError, "data", True),
    (errors.BackendError, "backend", False),
], ids=["usage", "expression", "input", "output", "data", "backend"])
def test_each_error_carries_its_exit_code(make, name, value_error):
    e = make("the message")
    assert isinstance(e, errors.PyramidError) and e.exit_code == errors.exit_code(name)
    assert isinstance(e, ValueError) is value_error
