"""``pyramid fill`` and ``pyramid blend`` (pyramid_cli.cli.methods): their options. The methods themselves:
tests/workflows/ and tests/run/."""

import json

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from helpers.images import write

pytestmark = pytest.mark.cli


def read(path) -> np.ndarray:
    inp = oiio.ImageInput.open(str(path))
    try:
        return inp.read_image("float")
    finally:
        inp.close()


@pytest.fixture
def holes(tmp_path):
    """A 16×16 RGBA picture: opaque noise with a transparent 4×4 square."""
    px = np.random.default_rng(0).random((16, 16, 4))
    px[..., 3] = 1
    px[6:10, 6:10] = 0
    return write(tmp_path / "holes.exr", px, names=("R", "G", "B", "A"), alpha=3)


def test_fill_json_is_the_only_output_and_the_result_is_opaque(holes, tmp_path):
    out = tmp_path / "filled.exr"
    r = invoke("fill", "--backend", "cpu", "--json", holes, out)
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)  # nothing else on standard output
    assert info["empty"] == 16 and info["partial"] == 0
    got = read(out)
    assert got.shape[2] == 4 and np.all(got[..., 3] == 1) and np.isfinite(got).all()
    np.testing.assert_allclose(got[:6, :, :3], read(holes)[:6, :, :3], rtol=0, atol=1e-6)  # known pixels kept


def test_fill_keep_alpha_keeps_the_cut_out(holes, tmp_path):
    out = tmp_path / "kept.exr"
    r = invoke("fill", "--backend", "cpu", "-q", "--keep-alpha", holes, out)
    assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(read(out)[..., 3], read(holes)[..., 3])


def test_fill_levels_out_of_range_exits_2(holes, tmp_path):
    r = invoke("fill", "--levels", "-1", holes, tmp_path / "o.exr")
    assert r.exit_code == 2 and not (tmp_path / "o.exr").exists()


@pytest.mark.parametrize("option", [["--weight-scale", "0"], ["--sweeps", "65"], ["--sweeps", "1,2,3"],
                                    ["--weight-scale", "a"]])
def test_fill_weight_scale_or_sweeps_out_of_range_exits_2(holes, tmp_path, option):
    r = invoke("fill", *option, holes, tmp_path / "o.exr")
    assert r.exit_code == 2 and not (tmp_path / "o.exr").exists() and option[0] in r.output


def test_fill_classic_options_equal_the_api_and_json_names_them(holes, tmp_path):
    """``--weight-scale 4 --sweeps 0 --analysis box4`` is pyr.fill's classic pull-push; --json says what ran."""
    import pyramid_cli as pyr

    r = invoke("fill", "--backend", "cpu", "--json", "--analysis", "box4", "--weight-scale", "4", "--sweeps", "0",
               holes, tmp_path / "c.exr")
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    assert info["weight_scale"] == [4, 4] and info["sweeps"] == [0, 0] and info["analysis"] == "box4"
    src = read(holes)
    want = pyr.fill(src, analysis="box4", weight_scale=4, sweeps=0, backend="cpu")
    np.testing.assert_allclose(read(tmp_path / "c.exr"), want, rtol=0, atol=1e-6)
    r = invoke("fill", "--backend", "cpu", "--json", holes, tmp_path / "d.exr")
    assert json.loads(r.stdout)["weight_scale"] == [16, 2] and json.loads(r.stdout)["sweeps"] == [1, 4]


def test_blend_json_and_a_mask_of_ones_gives_a_back(tmp_path):
    rng = np.random.default_rng(1)
    a = write(tmp_path / "a.exr", rng.random((16, 16, 3)))
    b = write(tmp_path / "b.exr", rng.random((16, 16, 3)))
    mask = write(tmp_path / "m.exr", np.ones((16, 16, 1)))
    out = tmp_path / "out.exr"
    r = invoke("blend", "--backend", "cpu", "--json", "--levels", "2", a, b, mask, out)
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    assert (info["width"], info["height"], info["levels"]) == (16, 16, 2)
    np.testing.assert_allclose(read(out), read(a), rtol=0, atol=1e-5)
