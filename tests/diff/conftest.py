"""Fixtures of the ``pyramid diff`` tests."""

from pathlib import Path

import pytest

from helpers.golden_tree import make_tree


@pytest.fixture
def tree(tmp_path: Path) -> tuple[Path, Path]:
    """out/ and golden/ (helpers.golden_tree.make_tree): a passing pair, a failing pair, a missing golden, an extra
    golden, a pair passing through an alternative reference, a warning-free match in a subfolder."""
    return make_tree(tmp_path)
