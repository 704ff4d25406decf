"""Pyramid blur: planned as one job, equal to the reference composed level by level."""

import numpy as np
import pytest
from click.testing import CliRunner

from pyramid_cli import emulate, reference
from pyramid_cli.cli import main
from pyramid_cli.parse import parse
from pyramid_cli.pyramids import (
    ANALYSIS,
    SYNTHESIS,
    blur_plan,
    blur_reference,
    impulse_sigma,
    lattice_mismatch,
    level_sizes,
)


def reference_blur(g, levels, analysis, synthesis, quasi=False):
    """m reference analysis steps, then m synthesis steps, each cropped to the level's size (written here,
    independently of pyramids.blur_reference, which the next test checks against it)."""
    sizes = level_sizes(g.shape[:2], levels)
    x = g
    for _ in range(levels):
        x = reference.run(parse(f"{analysis} *v g"), x)
    if quasi:
        x = reference.run(parse("quasi * g"), x)
    for k in range(levels, 0, -1):
        x = reference.run(parse(f"{synthesis} *^ g"), x)[:sizes[k - 1][0], :sizes[k - 1][1]]
    return x


def test_library_blur_reference_matches():
    g = np.random.default_rng(5).random((19, 23, 2))
    np.testing.assert_allclose(blur_reference(g, 3, "quadratic", "cubic", True),
                               reference_blur(g, 3, "quadratic", "cubic", True), atol=0)


@pytest.mark.parametrize("analysis", ANALYSIS)
@pytest.mark.parametrize("synthesis", SYNTHESIS)
def test_blur_plan_equals_reference_levels(analysis, synthesis):
    rng = np.random.default_rng(11)
    for shape, levels in [((1, 1), 1), ((5, 3), 2), ((17, 13), 3), ((64, 64), 4), ((33, 70), 5)]:
        g = rng.random(shape + (3,))
        got = emulate.run(blur_plan(shape, levels, analysis, synthesis), g)
        np.testing.assert_allclose(got, reference_blur(g, levels, analysis, synthesis), atol=1e-12)


def test_blur_with_quasi_prefilter():
    g = np.random.default_rng(3).random((23, 19))
    got = emulate.run(blur_plan(g.shape, 2, "box4", "cubic", quasi=True), g)
    np.testing.assert_allclose(got, reference_blur(g, 2, "box4", "cubic", quasi=True), atol=1e-12)


def test_blur_is_one_plan_without_readback_between_levels():
    p = blur_plan((64, 64), 3, "box4", "doosabin")
    # 3 × box4 (2 passes each) + 3 × doosabin (1 pass each), one chain of images
    assert len(p.passes) == 9
    assert [ps.target for ps in p.passes] == list(range(1, 10))


def test_lattice_warning_only_for_mixed_lattices():
    assert lattice_mismatch("box4", "doosabin") is None
    assert lattice_mismatch("cubic", "cubic") is None
    assert "dual" in lattice_mismatch("box4", "midpoint")


def test_blur_strength_grows_with_levels():
    sigmas = [impulse_sigma(m, "box4", "doosabin") for m in range(1, 5)]
    assert all(b > 1.8 * a for a, b in zip(sigmas, sigmas[1:], strict=False))


def test_blur_command_cpu(tmp_path):
    import OpenImageIO as oiio

    g = np.random.default_rng(1).random((20, 30, 3)).astype(np.float32)
    src, dst = tmp_path / "in.exr", tmp_path / "out.exr"
    out = oiio.ImageOutput.create(str(src))
    out.open(str(src), oiio.ImageSpec(30, 20, 3, "float"))
    out.write_image(g)
    out.close()
    r = CliRunner().invoke(main, ["blur", "--backend", "cpu", "--levels", "3", str(src), str(dst)])
    assert r.exit_code == 0, r.output
    px = oiio.ImageInput.open(str(dst)).read_image("float")
    np.testing.assert_allclose(px, reference_blur(g.astype(np.float64), 3, "box4", "doosabin"), atol=1e-5)
