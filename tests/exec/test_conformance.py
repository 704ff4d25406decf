"""Every executor against the float64 oracle (``reference``) and the plan's living definition (``emulate``).

One suite for all executors: each test takes the ``executor`` fixture (tests/conftest.py), which runs it once
per executor (the plan emulator in float64, the compiled CPU executor, GL; GL tests carry the ``gl`` mark).
A new executor joins every test here by one entry in ``conftest.EXECUTORS``. What only one executor does
(kernel caches, shader text, texture limits, threads) is tested in its own file (tests/exec/cpu/, tests/exec/gl/).

The fast tier runs the grid on three sizes and the borders on a few filters with one strategy; the rest is
``slow``.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cases import CHAINS as WRITTEN
from helpers.cases import GRID_CHANNELS, GRID_SIZES, NAMED, several_inputs_and_outputs
from helpers.marks import slow_beyond, slow_unless
from pyramid_cli.core.border import Border
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import check, plan
from pyramid_cli.reference import filters as reference

# Every named filter, every written chain, and g itself (an empty plan).
CHAINS = NAMED + [c for c in WRITTEN if c not in NAMED] + ["g"]
SIZES = slow_unless(GRID_SIZES, [(17, 13)])  # the fast tier: odd sizes over two levels
BORDERS = ["clamp", "mirror", "wrap", "zero"]
BORDER_SIZES = [(1, 1), (1, 7), (7, 1), (5, 3), (17, 13), (40, 33), (90, 77)]  # the last: interior + strips
BORDER_CHAINS = NAMED + ["doosabin *^ (box4 *v g)", "box\\ *v bartlett", "(box4)^2 *v g",
                         "1/16 [1 2 1; 2 4 2; 1 2 1] * g", "1/8 [1 2 1; 0 2 0; 1 0 1] *v g", "[1 -1] * g"]


def random_image(size, channels, seed) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(size if channels is None else size + (channels,))


def planned(text, size, strategy="cost", border="clamp"):
    expr = parse(text)
    p = plan(expr, size, strategy, border)
    check(p)
    return expr, p


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("text", CHAINS)
def test_equals_reference(executor, text, size):
    seed = CHAINS.index(text) * len(GRID_SIZES) + GRID_SIZES.index(size)
    channels = GRID_CHANNELS[seed % len(GRID_CHANNELS)]
    image = executor.pixels(random_image(size, channels, seed))
    expr, p = planned(text, size)
    out = executor.executor.run(p, image)
    assert out.dtype == executor.dtype and out.shape == p.output.size + image.shape[2:]
    assert out.flags.c_contiguous
    np.testing.assert_allclose(out, reference.run(expr, image), rtol=0, atol=executor.atol)
    np.testing.assert_allclose(out, emulate.run(p, image), rtol=0, atol=executor.atol)


@pytest.mark.parametrize("strategy", ["cost", pytest.param("paper", marks=pytest.mark.slow)])
@pytest.mark.parametrize("border", BORDERS)
@pytest.mark.parametrize("text", slow_unless(BORDER_CHAINS, ["doosabin *^ (box4 *v g)", "[1 -1] * g"]))
def test_every_border_equals_reference(executor, text, border, strategy):
    rng = np.random.default_rng(len(text))
    for i, size in enumerate(BORDER_SIZES):
        image = executor.pixels(rng.standard_normal(size + (3,) if i % 2 or size[0] > 50 else size))
        expr, p = planned(text, size, strategy, border)
        assert p.border == border and p.images[0].border == border
        np.testing.assert_allclose(executor.executor.run(p, image), reference.run(expr, image, Border(border)),
                                   rtol=0, atol=executor.atol, err_msg=f"{text} {border} {size}")


@pytest.mark.parametrize("channels", [None, 4, 6])
def test_several_inputs_and_outputs(executor, channels):
    """A Laplacian-style job: two inputs, intermediate levels read back (and read again later), the input itself
    read back (a copy, never the caller's array)."""
    size = (17, 13)
    p = several_inputs_and_outputs(size)
    images = [executor.pixels(random_image(size, channels, 20)), executor.pixels(random_image(size, channels, 21))]
    outs = executor.executor.run_outputs(p, images)
    want = emulate.run_outputs(p, images)
    assert [o.shape for o in outs] == [w.shape for w in want]
    for o, w in zip(outs, want, strict=True):
        assert o.dtype == executor.dtype
        np.testing.assert_allclose(o, w, rtol=0, atol=executor.atol)
    np.testing.assert_array_equal(outs[0], images[0])
    if executor.dtype == np.float32:  # the float64 emulator hands a float64 input back as it is
        assert not np.shares_memory(outs[0], images[0])
    np.testing.assert_allclose(executor.executor.run(p, images), want[-1], rtol=0, atol=executor.atol)


@pytest.mark.parametrize("channels", slow_beyond([None, 4, 1, 3, 6], 2))
@pytest.mark.parametrize("text", ["doosabin *^ (box4 *v g)", "fourpoint", "quadratic"])
def test_half_inputs_and_outputs_match_float_exactly(float32_executor, text, channels):
    """Half in: read exactly (a table on the CPU, the upload on GL), never a rounded copy. Half out: the float32
    result rounded to nearest even, like numpy."""
    ex = float32_executor.executor
    size = (37, 23)
    image = random_image(size, channels, 11).astype(np.float16)
    expr, p = planned(text, size)
    as_float = ex.run(p, image.astype(np.float32))
    np.testing.assert_allclose(as_float, reference.run(expr, image.astype(np.float32)), rtol=0, atol=1e-5)
    np.testing.assert_array_equal(ex.run(p, image), as_float)
    (half,) = ex.run_outputs(p, [image], dtype=np.float16)
    assert half.dtype == np.float16 and half.shape == as_float.shape
    np.testing.assert_array_equal(half.view(np.uint16), as_float.astype(np.float16).view(np.uint16))
