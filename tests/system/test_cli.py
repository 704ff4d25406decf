"""The command line as a user meets it, end to end: apply on real files, colour, faults, every command on every
backend, a reader closing stdout. Each command's own options: tests/cli/test_<module>.py."""

import os
import subprocess
import sys

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from helpers.images import read_with_spec as read
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference

pytestmark = pytest.mark.cli


def write_exr(path, pixels, pixel_type="float"):
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], pixel_type)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(pixels.astype(np.float32))
    out.close()




def test_apply_missing_input_exits_3(tmp_path):
    r = invoke("apply", "--backend", "cpu", "box", str(tmp_path / "nope.exr"), str(tmp_path / "o.exr"))
    assert r.exit_code == 3
    assert "nope.exr" in r.output


def test_apply_refuses_to_overwrite_its_input(tmp_path):
    src = tmp_path / "in.exr"
    write_exr(src, np.zeros((4, 4, 3)))
    before = src.read_bytes()
    r = invoke("apply", "--backend", "cpu", "box", str(src), str(src))
    assert r.exit_code == 4 and src.read_bytes() == before


def test_srgb_gradient_blur_matches_linear_light_not_gamma_space(tmp_path):
    """An 8-bit sRGB gradient is linearised, blurred, re-encoded (issue: colour in linear light)."""
    x = np.linspace(0, 1, 64)
    enc = np.repeat(np.repeat(x[None, :, None], 8, axis=0), 3, axis=2)
    enc[:, ::2] = 0  # alternate black columns so that averaging differs a lot between the two spaces
    src, dst = tmp_path / "grad.png", tmp_path / "blur.png"
    out = oiio.ImageOutput.create(str(src))
    out.open(str(src), oiio.ImageSpec(64, 8, 3, "uint8"))
    out.write_image(np.round(enc * 255).astype(np.uint8))
    out.close()
    r = invoke("apply", "--backend", "cpu", "box *v g", str(src), str(dst))
    assert r.exit_code == 0, r.output
    got, _ = read(dst)

    def to_linear(v):
        return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)

    def to_srgb(v):
        return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)

    stored = np.round(enc * 255) / 255
    linear = to_srgb(reference.run(parse("box *v g"), to_linear(stored)))
    gamma = reference.run(parse("box *v g"), stored)
    assert np.abs(got - linear).max() <= 1 / 255 + 1e-6
    assert np.abs(got - gamma).max() > 20 / 255


@pytest.mark.slow
def test_without_egl_auto_falls_back_with_a_warning_and_gl_exits_6(tmp_path):
    src = tmp_path / "in.exr"
    write_exr(src, np.random.default_rng(3).random((9, 7, 3)))
    env = {**os.environ, "__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent.json"}
    base = [sys.executable, "-m", "pyramid_cli.cli", "apply", "quadratic"]
    auto = subprocess.run(base + [str(src), str(tmp_path / "a.exr")], capture_output=True, text=True, env=env)
    assert auto.returncode == 0, auto.stderr
    warning = [ln for ln in auto.stderr.splitlines() if "warning" in ln]
    assert len(warning) == 1 and "apt-get install" in warning[0] and "running on the CPU" in warning[0]
    gl = subprocess.run(base[:4] + ["--backend", "gl", "quadratic", str(src), str(tmp_path / "b.exr")],
                        capture_output=True, text=True, env=env)
    assert gl.returncode == 6 and "--backend cpu" in gl.stderr
    assert not (tmp_path / "b.exr").exists()


@pytest.mark.parametrize("channels", [3, 4])
def test_half_exr_blur_stays_half_and_rounds_once(gl, tmp_path, channels):
    """A half file is uploaded as is and read back rounded once: the float result rounded to half."""
    from pyramid_cli.reference.pyramids import blur_reference
    from pyramid_cli.workflows.pyramids import blur_plan

    g = np.random.default_rng(5).random((33, 47, channels)).astype(np.float16)
    src, dst = tmp_path / "in.exr", tmp_path / "out.exr"
    write_exr(src, g.astype(np.float32), "half")
    r = invoke("blur", "--backend", "gl", "--levels", "2", "-q", str(src), str(dst))
    assert r.exit_code == 0, r.output
    inp = oiio.ImageInput.open(str(dst))
    assert str(inp.spec().format) == "half"
    got = np.asarray(inp.read_image("half"))
    inp.close()
    as_float = gl.run(blur_plan((33, 47), 2), g.astype(np.float32))
    np.testing.assert_array_equal(got.view(np.uint16), as_float.astype(np.float16).view(np.uint16))
    want = blur_reference(g.astype(np.float64), 2)
    np.testing.assert_allclose(got, want, rtol=2 ** -11, atol=1e-7)


def test_cpu_backend_loads_its_kernels_while_the_input_decodes(tmp_path, monkeypatch):
    """The header is read first and the session prepares in the background (numba and the plan's kernels
    for a half input) before the pixels are read; the run waits for it."""
    from pyramid_cli.exec.session import Session

    calls = []
    real = Session.prepare_async

    def spy(self, work, sizes, count=1, dtype=None):
        calls.append((work.label, [tuple(s) for s in sizes], count, np.dtype(dtype) if dtype is not None else None))
        return real(self, work, sizes, count, dtype)

    monkeypatch.setattr(Session, "prepare_async", spy)
    src = tmp_path / "in.exr"
    write_exr(src, np.random.default_rng(6).random((9, 7, 3)), "half")
    r = invoke("blur", "--backend", "cpu", "--levels", "2", "-q", str(src), str(tmp_path / "o.exr"))
    assert r.exit_code == 0, r.output
    assert calls[0] == ("blur", [(9, 7, 3)], 1, np.dtype(np.float16))


@pytest.mark.parametrize("backend", ["cpu", "reference"])
def test_every_backend_runs_every_command(tmp_path, backend):
    src = tmp_path / "in.exr"
    write_exr(src, np.random.default_rng(8).random((9, 11, 4)))
    for args in (["apply", "quadratic"], ["blur", "--levels", "2", "--border", "wrap"], ["mipmap", "--tile", "16"]):
        out = tmp_path / f"{args[0]}.exr"
        r = invoke(args[0], "--backend", backend, "-q", *args[1:], str(src), str(out))
        assert r.exit_code == 0 and out.exists(), r.output
    r = invoke("levels", "--backend", backend, "--laplacian", "--multipart", "-q", str(src), str(tmp_path / "b.exr"))
    assert r.exit_code == 0, r.output
    r = invoke("collapse", "--backend", backend, "-q", str(tmp_path / "b.exr"), str(tmp_path / "back.exr"))
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(read(tmp_path / "back.exr")[0], read(src)[0], rtol=0, atol=2e-3)


def _console(*args: str) -> list[str]:
    """The console script's entry point (``run``), as a process."""
    return [sys.executable, "-m", "pyramid_cli.cli", *args]


@pytest.mark.slow
@pytest.mark.parametrize("broken", [False, True], ids=["all-good", "one-bad"])
def test_a_reader_closing_stdout_loses_no_frame_and_changes_no_exit_code(tmp_path, broken):
    """`pyramid blur 'in/*.png' -o … | head -1`: the reader goes after one line, and the run goes on (issue 22)."""
    import pyramid_cli as pyr

    (tmp_path / "in").mkdir()
    rng = np.random.default_rng(12)
    for k in range(12):
        pyr.write_image(tmp_path / "in" / f"f{k:02d}.png", rng.random((48, 40, 3)), pixel_type="uint8")
    if broken:
        (tmp_path / "in" / "f12.png").write_bytes(b"")  # refused before libpng opens it (which prints on its own)
    args = ["blur", "--backend", "cpu", "--levels", "2", "in/*.png", "-o", "out/{stem}.png"]
    proc = subprocess.Popen(_console(*args, *(["--keep-going"] if broken else [])), cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().startswith("wrote out/f")
    proc.stdout.close()  # the reader is gone
    try:
        code = proc.wait(timeout=120)
    finally:
        proc.kill()
    err = proc.stderr.read()
    summary = f"pyramid: 12 written, 0 up to date, {int(broken)} failed\n"
    if broken:
        assert code == 3 and err.startswith(summary) and "f12.png" in err and err.count("\n") == 2, err
    else:
        assert code == 0 and err == summary, err
    assert sorted(os.listdir(tmp_path / "out")) == [f"f{k:02d}.png" for k in range(12)]  # no temporaries
    for k in range(12):
        src = pyr.read_image(tmp_path / "in" / f"f{k:02d}.png").pixels
        np.testing.assert_allclose(pyr.read_image(tmp_path / "out" / f"f{k:02d}.png").pixels,
                                   pyr.blur(src, 2, backend="cpu"), rtol=0, atol=1 / 255 + 1e-6)
