"""bench/torch_peer.py, the PyTorch peer of the GPU benchmark, equals the numpy reference at every pixel.

Skipped where torch is not installed (CI does not install it: it is the ``bench-gpu`` extra).
Runs on the CPU; the same code runs on CUDA in ``bench/run.py --only gpu``.
"""

from __future__ import annotations

import importlib.util
import sys
from fractions import Fraction

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from helpers.paths import ROOT  # noqa: E402
from pyramid_cli.core.expr import Named, Op  # noqa: E402
from pyramid_cli.core.parse import parse  # noqa: E402
from pyramid_cli.reference import filters as reference  # noqa: E402
from pyramid_cli.reference import pyramids  # noqa: E402

_spec = importlib.util.spec_from_file_location("bench_torch_peer", ROOT / "bench" / "torch_peer.py")
tp = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = tp  # dataclasses look their module up there
_spec.loader.exec_module(tp)

SIZES = [(1, 1), (7, 5), (37, 23), (129, 67)]
CHANNELS = [1, 3, 4]
DTYPES = {"float64": (torch.float64, 1e-12), "float32": (torch.float32, 1e-5)}


def image(rows: int, cols: int, channels: int, seed: int = 0) -> np.ndarray:
    """Noise with a gradient and an offset per channel; (H, W) for one channel, as the tool passes it."""
    rng = np.random.default_rng(seed + 1000 * rows + cols)
    y = np.linspace(0, 1, rows)[:, None, None]
    x = np.linspace(0, 2, cols)[None, :, None]
    img = x + y + 0.25 * np.arange(channels)[None, None, :] + rng.standard_normal((rows, cols, channels))
    return img[:, :, 0] if channels == 1 else img


def through_torch(fn, img: np.ndarray, dtype) -> np.ndarray:
    out = tp.from_nchw(fn(tp.to_nchw(img, dtype=dtype)), flat=img.ndim == 2)
    return out.astype(np.float64)


def assert_close(got: np.ndarray, want: np.ndarray, atol: float) -> None:
    assert got.shape == want.shape
    err = np.abs(got - want)
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= atol, f"max error {err.max():.3g} at {worst}: {got[worst]} vs {want[worst]}"


@pytest.mark.parametrize("dtype", list(DTYPES))
@pytest.mark.parametrize("channels", CHANNELS)
@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_blur_equals_reference(size, channels, dtype):
    img = image(*size, channels)
    dt, atol = DTYPES[dtype]
    got = through_torch(lambda x: tp.blur(x, 5), img, dt)
    assert_close(got, pyramids.blur_reference(img, 5), atol)


@pytest.mark.parametrize("dtype", list(DTYPES))
@pytest.mark.parametrize("channels", CHANNELS)
@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_one_step_equals_reference(size, channels, dtype):
    img = image(*size, channels, seed=1)
    dt, atol = DTYPES[dtype]
    assert_close(through_torch(tp.box4_down, img, dt), reference.run(parse("box4 *v g"), img), atol)
    assert_close(through_torch(tp.doosabin_up, img, dt), reference.run(parse("doosabin *^ g"), img), atol)


@pytest.mark.parametrize("text", [
    "box *v g", "box^nw *v g", "quadratic *v g", "cubic *v g", "bartlett *v^2 g", "gauss5 * g", "quasi * g",
    "nearest *^ g", "midpoint *^ g", "cubic *^ g", "fourpoint *^ g",
    "doosabin *^ (box4)^2 *v g", "1/4 [1 2 1] *v g",
])
def test_other_filters_equal_reference(text):
    """The conv2d form is derived from the masks, not written for box4 and Doo-Sabin alone."""
    expr = parse(text)
    for size in [(1, 1), (6, 9), (13, 4)]:
        img = image(*size, 3, seed=2)
        got = through_torch(lambda x, expr=expr: tp.run_expr(expr, x), img, torch.float64)
        assert_close(got, reference.run(expr, img), 1e-12)


@pytest.mark.parametrize("levels,analysis,synthesis", [(1, "box4", "doosabin"), (3, "quadratic", "cubic"),
                                                       (2, "box", "midpoint"), (7, "box4", "doosabin")])
def test_other_blurs_equal_reference(levels, analysis, synthesis):
    img = image(45, 31, 4, seed=3)
    got = through_torch(lambda x: tp.blur(x, levels, analysis, synthesis), img, torch.float64)
    assert_close(got, pyramids.blur_reference(img, levels, analysis, synthesis), 1e-12)


def test_weights_come_from_the_catalogue():
    box4 = tp.conv_step(Op.DOWN, Named("box4"), 1)
    assert box4.stride == 2 and box4.kernel_size == (4, 4)
    assert {v for ch in box4.weights for row in ch for v in row} == {Fraction(1, 16)}
    ds = tp.conv_step(Op.UP, Named("doosabin"), 1)
    assert len(ds.weights) == 4 and all(sum(v for row in ch for v in row) == 1 for ch in ds.weights)


def test_batch_and_half_precision():
    """(N, C, H, W) with N > 1 runs each image apart; float16 stays float16 and near the reference."""
    imgs = [image(37, 23, 4, seed=s) for s in (4, 5)]
    x = torch.stack([tp.to_nchw(a, dtype=torch.float64)[0] for a in imgs])
    y = tp.blur(x, 5)
    for k, a in enumerate(imgs):
        assert_close(y[k].permute(1, 2, 0).numpy(), pyramids.blur_reference(a, 5), 1e-12)
    half = tp.blur(x.to(torch.float16), 5)
    assert half.dtype == torch.float16
    assert_close(half[0].permute(1, 2, 0).double().numpy(), pyramids.blur_reference(imgs[0], 5), 2e-2)


def test_copy_floor_copies():
    src = torch.arange(24, dtype=torch.float32).reshape(1, 2, 3, 4)
    dst = torch.empty_like(src)
    assert tp.copy_floor(src, dst) is dst and torch.equal(dst, src)
