"""Border modes belong to the Plan (docs/design.md §1): every executor runs clamp, mirror, wrap and zero.

The reference folds indices with :func:`pyramid_cli.core.border.fold`; the checker below folds
them independently, by the definitions in docs/design.md §1, so a wrong fold in both is caught.
"""

from __future__ import annotations

import numpy as np
import pytest

from pyramid_cli.core.border import Border, fold_index
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference

BORDERS = ["clamp", "mirror", "wrap", "zero"]
SIZES = [(1, 1), (1, 7), (7, 1), (5, 3), (17, 13)]
CHAIN_CASES = ["doosabin *^ (box4 *v g)", "box\\ *v bartlett", "(box4)^2 *v g", "1/16 [1 2 1; 2 4 2; 1 2 1] * g"]


def by_definition(i: int, n: int, border: str) -> int:
    """docs/design.md §1 spelled out: clamp … 1 1 | 1 … n | n n …; mirror … 2 1 | 1 … n | n n−1 …;
    wrap … n−1 n | 1 … n | 1 2 …; zero: 0 (reads zero) outside."""
    if 1 <= i <= n:
        return i
    if border == "clamp":
        return 1 if i < 1 else n
    if border == "zero":
        return 0
    ext = list(range(1, n + 1))
    if border == "wrap":
        return ext[(i - 1) % n]
    period = ext + ext[::-1]
    return period[(i - 1) % (2 * n)]


@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_fold_follows_the_definitions(border, n):
    for i in range(-3 * n - 2, 4 * n + 3):
        assert fold_index(i, n, Border(border)) == by_definition(i, n, border)


@pytest.mark.parametrize("border", BORDERS)
def test_reference_reads_the_border_by_definition(border):
    """bartlett ⊗ on a 1-D image computed by hand with the folded indices."""
    g = np.array([[1.0, 2.0, 4.0, 8.0, 16.0]])
    n = g.shape[1]
    want = [sum(w * (g[0, by_definition(c + d, n, border) - 1] if by_definition(c + d, n, border) else 0.0)
                for d, w in ((-1, 0.25), (0, 0.5), (1, 0.25))) for c in range(1, n + 1)]
    got = reference.run(parse("1/4 [1 2 1] * g"), g, Border(border))
    np.testing.assert_allclose(got[0], want, rtol=0, atol=1e-12)


def test_other_libraries_names_map_to_one_mode_each_and_reflect_is_refused():
    from pyramid_cli.core.border import BORDER_ALIASES, BORDER_NAMES, BORDER_REFUSED, canonical
    from pyramid_cli.core.errors import UsageError

    assert {canonical(name) for name in BORDER_NAMES} == set(BORDER_NAMES)
    assert all(canonical(alias.upper()) == mode in BORDER_NAMES for alias, mode in BORDER_ALIASES.items())
    assert not set(BORDER_ALIASES) & set(BORDER_REFUSED) and not set(BORDER_ALIASES) & set(BORDER_NAMES)
    # numpy's "symmetric" repeats the edge sample (our mirror); its "reflect" does not (no mode of ours)
    assert np.pad([1, 2, 3], 2, mode="symmetric").tolist() == [fold_index(i, 3, Border.MIRROR) for i in range(-1, 6)]
    assert np.pad([1, 2, 3], 2, mode="reflect").tolist() == [3, 2, 1, 2, 3, 2, 1]
    with pytest.raises(UsageError, match="'reflect' means two things"):
        canonical("reflect")
    with pytest.raises(UsageError, match=r"must be one of clamp, mirror, wrap, zero \(or edge, nearest"):
        canonical("reflex")


def test_the_aliases_text_names_every_alias_beside_its_mode():
    from pyramid_cli.core.border import BORDER_ALIASES, aliases_text

    text = aliases_text()
    for alias, mode in BORDER_ALIASES.items():
        assert f"{mode} (" in text and alias in text.split(f"{mode} (")[1].split(")")[0], (alias, mode)
