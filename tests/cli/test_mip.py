"""``pyramid mipmap`` (pyramid_cli.cli.mip): its wrap and border options. The textures themselves:
tests/workflows/ and tests/system/test_maketx.py."""

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from helpers.images import write

pytestmark = pytest.mark.cli


@pytest.fixture
def src(tmp_path):
    return write(tmp_path / "in.exr", np.random.default_rng(0).random((16, 16, 3)))


def wrapmodes(path) -> str:
    inp = oiio.ImageInput.open(str(path))
    try:
        return inp.spec().get_string_attribute("wrapmodes")
    finally:
        inp.close()


@pytest.mark.parametrize("args, modes", [([], "clamp,clamp"), (["--wrap", "periodic"], "periodic,periodic"),
                                         (["--border", "mirror"], "mirror,mirror"),
                                         (["--swrap", "black", "--twrap", "black"], "black,black")])
def test_wrap_and_border_reach_the_files_wrapmodes(src, tmp_path, args, modes):
    out = tmp_path / "out.tx.exr"
    r = invoke("mipmap", "--backend", "cpu", "-q", *args, src, out)
    assert r.exit_code == 0, r.output
    assert wrapmodes(out) == modes


@pytest.mark.parametrize("args, message", [
    (["--wrap", "periodic", "--border", "clamp"], "--border clamp contradicts --wrap periodic,periodic"),
    (["--swrap", "periodic", "--twrap", "clamp"], "differ per axis"),
    (["--wrap", "sideways"], "unknown wrap mode 'sideways'"),
    (["--tile", "4"], "--tile"),
])
def test_contradicting_or_bad_options_exit_2_before_any_work(src, tmp_path, args, message):
    r = invoke("mipmap", "--backend", "cpu", *args, src, tmp_path / "out.tx.exr")
    assert r.exit_code == 2 and message in r.output, r.output
    assert not (tmp_path / "out.tx.exr").exists()


def test_a_wrap_agreeing_with_border_is_accepted(src, tmp_path):
    r = invoke("mipmap", "--backend", "cpu", "-q", "--wrap", "periodic", "--border", "wrap", src, tmp_path / "o.exr")
    assert r.exit_code == 0, r.output
    assert wrapmodes(tmp_path / "o.exr") == "periodic,periodic"
