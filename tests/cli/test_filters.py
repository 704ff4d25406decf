"""``pyramid apply``, ``blur``, ``levels`` and ``collapse`` (pyramid_cli.cli.filters): their options on real
files. Bad input to them: tests/system/test_bad_input.py; every command on every backend: tests/system/test_cli.py."""

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.cli import invoke
from helpers.images import read_with_spec as read
from helpers.images import write as write_exr
from pyramid_cli.cli import main
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference

pytestmark = pytest.mark.cli




@pytest.mark.parametrize("pixel_type, tol", [("float", 1e-6), ("half", 2e-3)])
def test_apply_cpu_exr_in_exr_out_keeps_the_type(tmp_path, pixel_type, tol):
    g = np.random.default_rng(1).random((9, 7, 3)).astype(np.float32)
    src, dst = tmp_path / "in.exr", tmp_path / "out.exr"
    write_exr(src, g, pixel_type)
    r = invoke("apply", "--backend", "cpu", "quadratic *v g", str(src), str(dst))
    assert r.exit_code == 0, r.output
    px, spec = read(dst)
    assert spec.format == oiio.TypeDesc(pixel_type)
    g_read, _ = read(src)
    want = reference.run(parse("quadratic *v g"), g_read.astype(np.float64))
    np.testing.assert_allclose(px, want, atol=tol)


def test_apply_cpu_png(tmp_path):
    g = (np.random.default_rng(2).random((8, 8, 3)) * 255).astype(np.uint8)
    src, dst = tmp_path / "in.png", tmp_path / "out.png"
    out = oiio.ImageOutput.create(str(src))
    out.open(str(src), oiio.ImageSpec(8, 8, 3, "uint8"))
    out.write_image(g)
    out.close()
    r = invoke("apply", "--backend", "cpu", "doosabin", str(src), str(dst))
    assert r.exit_code == 0, r.output
    px, spec = read(dst)
    assert (spec.width, spec.height) == (16, 16) and spec.format == oiio.TypeDesc("uint8")


@pytest.mark.parametrize("border", ["mirror", "wrap", "zero"])
def test_gl_runs_non_clamp_borders_itself_and_says_so(gl, tmp_path, border):
    """--backend gl --border mirror runs on GL (the -v line names the executor that ran the image)."""
    from pyramid_cli.reference.pyramids import blur_reference

    g = np.random.default_rng(7).random((21, 13, 3))
    src, dst = tmp_path / "in.exr", tmp_path / "out.exr"
    write_exr(src, g)
    r = CliRunner().invoke(main, ["blur", "--backend", "gl", "--border", border, "--levels", "2", "-v", "--type",
                                  "float", str(src), str(dst)])
    assert r.exit_code == 0, r.output
    assert "executor gl (" in r.stderr and "executor cpu" not in r.stderr and "reference" not in r.stderr
    np.testing.assert_allclose(read(dst)[0], blur_reference(g.astype(np.float32).astype(np.float64), 2,
                                                            border=border), rtol=0, atol=1e-5)


def test_collapse_follows_the_recorded_synthesis_and_border_and_refuses_a_contradiction(tmp_path):
    src, bands = tmp_path / "in.exr", tmp_path / "bands.exr"
    g = np.random.default_rng(9).random((19, 23, 3))
    write_exr(src, g)
    r = invoke("levels", "-q", "--laplacian", "--multipart", "--synthesis", "chaikin", "--border", "wrap",
               "--backend", "cpu", str(src), str(bands))
    assert r.exit_code == 0, r.output
    r = invoke("collapse", "-q", "--backend", "cpu", str(bands), str(tmp_path / "back.exr"))
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(read(tmp_path / "back.exr")[0], g.astype(np.float32), rtol=0, atol=1e-5)
    for option in (["--synthesis", "cubic"], ["--border", "clamp"]):
        r = invoke("collapse", "-q", *option, str(bands), str(tmp_path / "wrong.exr"))
        assert r.exit_code == 2 and "would not give the image back" in r.stderr
        assert not (tmp_path / "wrong.exr").exists()
    r = invoke("collapse", "-q", "--synthesis", "doosabin", str(bands), str(tmp_path / "alias.exr"))  # chaikin's name
    assert r.exit_code == 0, r.output
