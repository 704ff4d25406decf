"""Blur strength as a standard deviation (pyramid_cli.core.sigma): the closed forms equal the evaluated kernels,
and the sigmas a run may ask for."""

import json
import math
from fractions import Fraction

import pytest

from helpers.marks import slow_beyond
from pyramid_cli.core import sigma as sigmas
from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.sigma import impulse_sigma


@pytest.mark.parametrize("analysis, synthesis", slow_beyond(
    [("box4", "doosabin"), ("quadratic", "cubic"), ("box", "nearest"), ("cubic", "fourpoint")], unpack=True))
def test_levels_sigma_equals_the_kernel_evaluation(analysis, synthesis):
    for m in range(1, 6):
        assert math.isclose(sigmas.levels_sigma(m, analysis, synthesis), impulse_sigma(m, analysis, synthesis),
                            rel_tol=1e-12)


@pytest.mark.slow
def test_sigma_blend_matches_the_kernel_evaluation():
    """The closed-form (m, t) equals the one found from the evaluated kernels (the planner's only source
    before the closed form: the first level count at or past sigma, blended with the one below)."""
    for sigma in (0.5, 1.4, 3.5, 10.0, 40.0):
        m, t = sigmas.sigma_blend(sigma)
        sig = [0.0]
        while sig[-1] < sigma:
            sig.append(impulse_sigma(len(sig), "box4", "doosabin"))
        m2 = len(sig) - 2
        t2 = (sigma ** 2 - sig[m2] ** 2) / (sig[m2 + 1] ** 2 - sig[m2] ** 2)
        assert m == m2 and math.isclose(t, t2, rel_tol=1e-9, abs_tol=1e-12)


@pytest.mark.parametrize("sigma", [float("inf"), float("nan"), -1.0, 0.0, 1e6])
def test_bad_sigmas_are_refused(sigma):
    with pytest.raises(UsageError):
        sigmas.check_sigma(sigma)


def test_sigma_beyond_the_image_is_refused_and_names_the_limit():
    top = sigmas.max_sigma((256, 320))
    sigmas.check_sigma(top * 0.99, (256, 320))
    with pytest.raises(UsageError, match=r"320×256 image.*9 levels"):
        sigmas.check_sigma(1000.0, (256, 320))


def test_blur_strength_grows_with_levels():
    sigmas = [impulse_sigma(m, "box4", "doosabin") for m in range(1, 5)]
    assert all(b > 1.8 * a for a, b in zip(sigmas, sigmas[1:], strict=False))


@pytest.fixture
def fresh_forms(tmp_path, monkeypatch):
    """The variance forms' cache in ``tmp_path``, none remembered in the process."""
    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    sigmas.variance_form.cache_clear()
    yield tmp_path / "plans"
    sigmas.variance_form.cache_clear()


def test_a_variance_form_is_computed_once_and_read_back(fresh_forms, monkeypatch):
    want = sigmas._variance_form("box4", "doosabin")
    assert sigmas.variance_form("box4", "doosabin") == want
    (entry,) = fresh_forms.iterdir()
    sigmas.variance_form.cache_clear()
    monkeypatch.setattr(sigmas, "_variance_form", lambda *a: pytest.fail("computed again"))
    got = sigmas.variance_form("box4", "doosabin")
    assert got == want and all(type(f) is Fraction for f in got)


@pytest.mark.parametrize("damage", [b"", b"{", b'{"key": "x", "form": [[1, 2], [3, 4]]}', b"\xff",
                                    b'{"key": KEY, "form": [[1, 0], [3, 4]]}', b'{"key": KEY, "form": [["1", 2]]}'])
def test_a_damaged_or_foreign_variance_form_is_recomputed(damage, fresh_forms):
    want = sigmas.variance_form("box4", "doosabin")
    (entry,) = fresh_forms.iterdir()
    key = json.loads(entry.read_bytes())["key"]
    entry.write_bytes(damage.replace(b"KEY", json.dumps(key).encode()))
    sigmas.variance_form.cache_clear()
    assert sigmas.variance_form("box4", "doosabin") == want
    assert json.loads(entry.read_bytes())["key"] == key  # rewritten


def test_an_unwritable_cache_folder_still_gives_the_form(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path / "file" / "below"))
    sigmas.variance_form.cache_clear()
    try:
        assert sigmas.variance_form("box4", "doosabin") == sigmas._variance_form("box4", "doosabin")
    finally:
        sigmas.variance_form.cache_clear()
