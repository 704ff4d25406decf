"""Pyramid blur: planned as one job, equal to the reference composed level by level."""

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.marks import slow_beyond
from helpers.oracles import reference_blur
from pyramid_cli.cli import main
from pyramid_cli.core.catalogue import ANALYSIS_FILTERS as ANALYSIS
from pyramid_cli.core.catalogue import SYNTHESIS_FILTERS as SYNTHESIS
from pyramid_cli.core.geometry import level_sizes
from pyramid_cli.core.parse import parse
from pyramid_cli.core.sigma import impulse_sigma
from pyramid_cli.exec import emulate
from pyramid_cli.reference import filters as reference
from pyramid_cli.workflows.pyramids import blur_plan, lattice_mismatch


@pytest.mark.parametrize("analysis", ANALYSIS)
@pytest.mark.parametrize("synthesis", slow_beyond(SYNTHESIS, 2))
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
    from pyramid_cli.core.expr import Named, Op
    from pyramid_cli.plan import choose_recipe

    p = blur_plan((64, 64), 3, "box4", "doosabin")
    # 3 × box4 (the paper's 2 passes or one fused, as the cost model picks per level) + 3 × doosabin
    # (1 pass each), one chain of images
    box4 = sum(len(choose_recipe(Op.DOWN, Named("box4"), 1, size)[0]) for size in level_sizes((64, 64), 2))
    assert len(p.passes) == box4 + 3
    assert [ps.target for ps in p.passes] == list(range(1, box4 + 4))
    assert len(blur_plan((64, 64), 3, "box4", "doosabin", strategy="paper").passes) == 9


def test_lattice_warning_only_for_mixed_lattices():
    assert lattice_mismatch("box4", "doosabin") is None
    assert lattice_mismatch("cubic", "cubic") is None
    assert "dual" in lattice_mismatch("box4", "midpoint")


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


# ---------------------------------------------------------------- levels, Laplacian, collapse, mipmap, sigma
from pyramid_cli import imageio as pio  # noqa: E402
from pyramid_cli.core.geometry import mip_levels  # noqa: E402
from pyramid_cli.workflows.pyramids import blur_plan_sigma, collapse_plan, levels_plan  # noqa: E402


def write_exr(path, px, pixel_type="float"):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(px.shape[1], px.shape[0], px.shape[2], pixel_type))
    out.write_image(px.astype(np.float32))
    out.close()


@pytest.mark.parametrize("analysis", ANALYSIS)
def test_gaussian_levels_equal_repeated_reference_reduce(analysis):
    g = np.random.default_rng(2).random((37, 29, 2))
    outs = emulate.run_outputs(levels_plan(g.shape[:2], 4, analysis), g)
    x = g
    for level in outs:
        x = reference.run(parse(f"{analysis} *v g"), x)
        np.testing.assert_allclose(level, x, atol=1e-12)


@pytest.mark.parametrize("synthesis", SYNTHESIS)
def test_laplacian_bands_collapse_back_exactly(synthesis):
    g = np.random.default_rng(4).random((37, 29, 3))
    bands = emulate.run_outputs(levels_plan(g.shape[:2], 4, "quadratic", True, synthesis), g)
    assert [b.shape[:2] for b in bands] == level_sizes(g.shape[:2], 4)
    # each band is G_k − expand(G_k+1) by the reference
    g1 = reference.run(parse("quadratic *v g"), g)
    np.testing.assert_allclose(bands[0], g - reference.run(parse(f"{synthesis} *^ g"), g1)[:37, :29], atol=1e-12)
    back = emulate.run(collapse_plan(tuple(b.shape[:2] for b in bands), synthesis), bands)
    np.testing.assert_allclose(back, g, atol=1e-12)


def test_levels_laplacian_then_collapse_cli_float_exr(tmp_path):
    g = (np.random.default_rng(6).random((45, 61, 3)) * 4).astype(np.float32)
    src = tmp_path / "in.exr"
    write_exr(src, g)
    r = CliRunner().invoke(main, ["levels", "--laplacian", "--multipart", "--levels", "4", str(src),
                                  str(tmp_path / "bands.exr"), "--sheet", str(tmp_path / "sheet.png")])
    assert r.exit_code == 0, r.output
    assert pio.count_parts(tmp_path / "bands.exr") == 5
    r = CliRunner().invoke(main, ["collapse", str(tmp_path / "bands.exr"), str(tmp_path / "back.exr")])
    assert r.exit_code == 0, r.output
    back = pio.read_image(tmp_path / "back.exr").pixels
    np.testing.assert_allclose(back, g, atol=1e-5)
    # one file per level, then collapse from the files
    r = CliRunner().invoke(main, ["levels", "--laplacian", "--levels", "3", str(src), str(tmp_path / "b_{level}.exr")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["collapse", str(tmp_path / "b_*.exr"), str(tmp_path / "back2.exr")])
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(pio.read_image(tmp_path / "back2.exr").pixels, g, atol=1e-5)


@pytest.mark.parametrize("shape", [(64, 64), (37, 50), (1, 9)])
def test_mipmap_round_up_is_read_by_openimageio_as_mipmapped(tmp_path, shape):
    import OpenImageIO as oiio

    g = np.random.default_rng(8).random(shape + (3,)).astype(np.float32)
    src, dst = tmp_path / "in.exr", tmp_path / "out.tx.exr"
    write_exr(src, g)
    r = CliRunner().invoke(main, ["mipmap", "--backend", "cpu", "--round", "up", "--tile", "16", str(src), str(dst)])
    assert r.exit_code == 0, r.output
    inp = oiio.ImageInput.open(str(dst))
    levels = []
    while inp.seek_subimage(0, len(levels)):
        spec = inp.spec()
        assert spec.tile_width == 16
        levels.append(inp.read_image(0, len(levels), 0, 3, "float"))
    inp.close()
    assert len(levels) == mip_levels(shape) + 1 and levels[-1].shape[:2] == (1, 1)
    x = g.astype(np.float64)
    np.testing.assert_allclose(levels[0], x, atol=0)
    for level in levels[1:]:
        x = reference.run(parse("quadratic *v g"), x)
        assert level.shape[:2] == x.shape[:2]
        np.testing.assert_allclose(level, x, atol=1e-6)


def test_sigma_changes_the_blur_continuously_and_monotonically():
    n = 129
    g = np.zeros((1, n))
    g[0, n // 2] = 1.0
    widths, images = [], []
    for sigma in np.linspace(0.6, 6.0, 28):
        out = emulate.run(blur_plan_sigma(g.shape, float(sigma))[0], g)[0]
        x = np.arange(n)
        mean = (out * x).sum() / out.sum()
        widths.append(np.sqrt((out * (x - mean) ** 2).sum() / out.sum()))
        images.append(out)
    assert all(b > a for a, b in zip(widths, widths[1:], strict=False))
    # continuity, also where the level count switches (σ₁ = √2, σ₂ = √10): a tiny change in sigma
    # gives a tiny change in the image
    for sigma in (0.9, np.sqrt(2) - 1e-9, 2.5, np.sqrt(10) - 1e-9, 5.0):
        a = emulate.run(blur_plan_sigma(g.shape, float(sigma))[0], g)
        for eps, bound in ((1e-2, 2e-2), (1e-4, 2e-4)):
            b = emulate.run(blur_plan_sigma(g.shape, float(sigma + eps))[0], g)
            assert np.abs(b - a).max() < bound, (sigma, eps)


def test_sigma_blend_has_the_requested_variance():
    for sigma in (0.7, 1.7, 3.3, 9.0):
        p, m, t = blur_plan_sigma((512, 512), sigma)
        lo = impulse_sigma(m, "box4", "doosabin") if m else 0.0
        hi = impulse_sigma(m + 1, "box4", "doosabin")
        assert 0 <= t <= 1
        assert abs(((1 - t) * lo ** 2 + t * hi ** 2) ** 0.5 - sigma) < 1e-9
