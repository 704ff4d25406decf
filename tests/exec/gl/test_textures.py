"""The GL executor's texture sizes, known without a context or the executor (:mod:`pyramid_cli.exec.gl.textures`)."""

from __future__ import annotations

from pyramid_cli.exec.gl.textures import texture_bytes, texture_size


def test_texture_sizes_are_powers_of_two():
    assert texture_size((1, 1)) == (1, 1)
    assert texture_size((2160, 3840)) == (4096, 4096)
    assert texture_size((129, 64)) == (256, 64)
    assert texture_size((0, 2)) == (1, 2)


def test_a_texture_holds_rgba_floats_at_its_power_of_two_size():
    assert texture_bytes((1, 1)) == 16
    assert texture_bytes((2160, 3840)) == 4096 * 4096 * 16
    assert texture_bytes((129, 64)) == 256 * 64 * 16


def test_the_executor_and_the_package_give_the_same_sizes():
    """Budgets (the executor's ``texture_bytes``) and auto's estimates (this module) count the same textures."""
    from pyramid_cli.exec.gl import GLExecutor
    from pyramid_cli.exec.gl import texture_size as exported

    assert GLExecutor.texture_bytes((1000, 3)) == texture_bytes((1000, 3)) == 1024 * 4 * 16
    assert exported is texture_size
