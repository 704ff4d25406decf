"""The error types and their one table of exit codes (pyramid_cli.core.errors)."""

import pytest

from pyramid_cli.core import errors


def test_exit_codes_are_distinct_and_documented():
    codes = [code for code, _ in errors.EXIT_CODES.values()]
    assert len(set(codes)) == len(codes)
    assert errors.exit_code("ok") == 0 and errors.exit_code("usage") == 2 and errors.exit_code("interrupted") == 130
    assert all(why for _, why in errors.EXIT_CODES.values())


@pytest.mark.parametrize("make, name, value_error, os_error", [
    (errors.UsageError, "usage", True, False), (lambda m: errors.ExpressionError(m, "box *", 4), "usage", True, False),
    (errors.InputError, "input", False, True), (errors.OutputError, "output", False, True),
    (errors.DataError, "data", True, False), (errors.BackendError, "backend", False, False),
], ids=["usage", "expression", "input", "output", "data", "backend"])
def test_each_error_carries_its_exit_code(make, name, value_error, os_error):
    e = make("the message")
    assert isinstance(e, errors.PyramidError) and e.exit_code == errors.exit_code(name)
    assert isinstance(e, ValueError) is value_error and isinstance(e, OSError) is os_error
    assert str(e) == e.message.splitlines()[0] or name == "usage"


def test_file_errors_pickle_and_say_their_message():  # a Dask worker's failure comes back to the client pickled
    import pickle

    e = pickle.loads(pickle.dumps(errors.InputError("cannot read a.exr: no such file")))
    assert type(e) is errors.InputError and str(e) == e.message == "cannot read a.exr: no such file"
    assert e.errno is None and e.exit_code == 3


def test_every_warning_is_a_pyramid_warning_at_the_callers_line():
    for category in (errors.MixedLatticeWarning, errors.MaskWarning, errors.BackendWarning):
        assert issubclass(category, errors.PyramidWarning) and issubclass(category, UserWarning)
    with pytest.warns(errors.MaskWarning, match="clipped") as caught:
        errors.warn("3 values clipped", errors.MaskWarning)
    assert caught[0].filename == __file__
