"""The Python API (``import pyramid_cli as pyr``) against the float64 reference, on every backend present."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

import pyramid_cli as pyr
from helpers.marks import slow_beyond
from pyramid_cli import api
from pyramid_cli.core.border import Border
from pyramid_cli.core.errors import PyramidError, UsageError
from pyramid_cli.core.geometry import mip_levels
from pyramid_cli.core.parse import parse
from pyramid_cli.core.sigma import sigma_blend
from pyramid_cli.reference import filters as reference
from pyramid_cli.reference import pyramids
from pyramid_cli.reference.mip import mip_reference

SIZES = [(1, 1), (1, 7), (5, 3), (17, 13), (129, 67)]
CHANNELS = [1, 3, 4, 6]


@pytest.fixture(scope="module")
def sessions(gl_executor):
    made = {name: pyr.Session(name) for name in ("gl", "cpu", "reference")}
    yield made
    for s in made.values():
        s.close()


def image(size, channels, seed=0):
    """float32 pixels: every executor's own width (float64 inputs run on the CPU executor's float64 kernels, held to
    the reference in tests/exec/cpu/test_float64.py)."""
    a = np.random.default_rng(seed).random(size + (channels,)).astype(np.float32)
    return a[:, :, 0] if channels == 1 else a  # one channel as a 2-D array


def cases(a):
    """(name, call(session), reference outputs) for every API function on ``a``."""
    f64 = a.astype(np.float64)
    return [
        ("apply", lambda s: [pyr.apply("quadratic *v g", a, session=s)], [reference.run(parse("quadratic *v g"), f64)]),
        ("apply mirror", lambda s: [pyr.apply("gauss5", a, border="mirror", session=s)],
         [reference.run(parse("gauss5"), f64, Border.MIRROR)]),
        ("blur", lambda s: [pyr.blur(a, 3, session=s)], [pyramids.blur_reference(f64, 3)]),
        ("blur sigma", lambda s: [pyr.blur(a, sigma=1.2, border="wrap", session=s)],
         [pyramids.blur_blend_reference(f64, *sigma_blend(1.2), border="wrap")]),
        ("pyramid", lambda s: list(pyr.pyramid(a, session=s)),
         pyramids.levels_reference(f64, mip_levels(a.shape[:2]))),
        ("laplacian", lambda s: pyr.laplacian(a, 3, analysis="quadratic", synthesis="cubic", session=s),
         pyramids.laplacian_reference(f64, 3, "quadratic", "cubic")),
        ("collapse", lambda s: [pyr.collapse(pyramids.laplacian_reference(f64, 2), session=s)], [f64]),
        ("mipmap", lambda s: pyr.mipmap(a, border="zero", session=s), mip_reference(f64, "quadratic", "zero")),
        ("mipmap up", lambda s: pyr.mipmap(a, border="zero", rounding="up", session=s),
         pyramids.levels_reference(f64, mip_levels(a.shape[:2]), "quadratic", "zero")),
    ]


@pytest.mark.gl
@pytest.mark.parametrize("channels", CHANNELS)
@pytest.mark.parametrize("size", slow_beyond(SIZES, 3), ids=lambda s: f"{s[0]}x{s[1]}")
def test_every_function_equals_the_reference_on_every_backend(sessions, size, channels):
    a = image(size, channels, seed=size[0] * 7 + channels)
    for name, call, want in cases(a):
        for backend, s in sessions.items():
            got = call(s)
            assert len(got) == len(want), (name, backend)
            for k, (g, w) in enumerate(zip(got, want, strict=True)):
                assert g.shape == w.shape, (name, backend, k)
                np.testing.assert_allclose(g, w, rtol=0, atol=1e-5, err_msg=f"{name} on {backend}, output {k}")


def test_pyramid_level_zero_is_a_copy_of_the_input_and_goes_down_to_one_pixel():
    a = np.random.default_rng(3).random((17, 13, 3)).astype(np.float32)
    levels = list(pyr.pyramid(a, backend="cpu"))
    assert levels[0] is not a and not np.shares_memory(levels[0], a)
    np.testing.assert_array_equal(levels[0], a)
    assert levels[-1].shape == (1, 1, 3) and [lv.shape[:2] for lv in levels][1] == (9, 7)
    assert len(list(pyr.pyramid(a, levels=2, backend="cpu"))) == 3


@pytest.mark.parametrize("backend", ["cpu", "reference"])
def test_collapse_inverts_laplacian(backend):
    a = np.random.default_rng(4).random((129, 67, 4))
    np.testing.assert_allclose(pyr.collapse(pyr.laplacian(a, 5, backend=backend), backend=backend), a,
                               rtol=0, atol=1e-5)


@pytest.mark.gl
@pytest.mark.slow
def test_a_session_compiles_each_program_once_over_200_arrays(gl_executor):
    rng = np.random.default_rng(5)
    with pyr.Session("gl") as s:
        for _ in range(200):
            pyr.blur(rng.random((24, 20, 3)), 3, session=s)
        programs = {ps for ps in s.executor._programs}
        assert s.executor.compiles == len(programs) > 0


def test_integer_arrays_are_normalised_codes():
    u8 = np.full((4, 4), 255, dtype=np.uint8)
    i16 = np.full((4, 4), -32768, dtype=np.int16)
    np.testing.assert_allclose(pyr.apply("box * g", u8, dtype=np.float32, backend="cpu"), 1.0)
    np.testing.assert_allclose(pyr.apply("box * g", i16, dtype=np.float32, backend="cpu"), -1.0)
    np.testing.assert_array_equal(pyr.apply("box * g", i16, backend="cpu"), -32767)  # codes clip at -max
    np.testing.assert_allclose(pyr.blur(np.ones((6, 6), dtype=bool), 1, backend="cpu"), 1.0)
    assert pyr.blur(np.ones((6, 6), dtype=bool), 1, backend="cpu").dtype == np.float32


@pytest.mark.parametrize(("call", "message"), [
    (lambda: pyr.blur(np.ones(5)), "expected a 2-D (H, W) or 3-D (H, W, C) array, got shape (5,)"),
    (lambda: pyr.blur(np.ones((2, 2, 2, 2))), "got shape (2, 2, 2, 2)"),
    (lambda: pyr.blur(np.ones((0, 4))), "an image needs at least one row, column and channel"),
    (lambda: pyr.blur(np.ones((4, 4), dtype=complex)), "pixels must be real numbers"),
    (lambda: pyr.blur(np.ones((4, 4)), analysis="doosabin"),
     "'doosabin' is a synthesis filter (four phase masks): use it with ⊗↑, not ⊗↓"),
    (lambda: pyr.blur(np.ones((4, 4)), synthesis="box4"), "'box4' is a single mask for ⊗ and ⊗↓"),
    (lambda: pyr.apply("bartlet * g", np.ones((4, 4))), "unknown filter 'bartlet' (did you mean 'bartlett'?)"),
    (lambda: pyr.apply("box * g", np.ones((4, 4)), border="reflex"), "border must be one of clamp, mirror"),
    (lambda: pyr.apply("box * g", np.ones((4, 4)), border="reflect"), "border 'reflect' means two things"),
    (lambda: pyr.apply("box * g", np.ones((4, 4)), backend="cuda"), "backend must be one of auto, gl, cpu"),
    (lambda: pyr.blur(np.ones((4, 4)), 0), "levels must be 1 to 16"),
    (lambda: pyr.collapse([np.ones((4, 4)), np.ones((3, 3))]), "band 1 has shape (3, 3)"),
])
def test_bad_arguments_raise_value_errors_with_the_cli_message(call, message):
    with pytest.raises(ValueError) as info:
        call()
    assert message in str(info.value)


def test_project_errors_are_pyramid_errors():
    with pytest.raises(PyramidError):
        pyr.apply("doosabin * g", np.ones((3, 3)))


def test_data_errors_are_value_errors_as_the_readme_says_and_file_errors_os_errors(tmp_path):
    from pyramid_cli.core.errors import DataError, InputError

    with pytest.raises(ValueError, match="no known pixel") as info:
        pyr.fill(np.zeros((4, 4)), mask=np.zeros((4, 4)), backend="cpu")
    assert isinstance(info.value, DataError)
    with pytest.raises(OSError) as info:
        pyr.read_image(tmp_path / "missing.exr")
    assert isinstance(info.value, InputError) and not isinstance(info.value, ValueError)
    for name in ("UsageError", "DataError", "InputError", "OutputError", "BackendError"):
        assert name in api.__doc__


@pytest.mark.parametrize("backend", ["cpu", "reference"])
def test_collapse_uses_the_synthesis_and_border_the_bands_were_made_with_and_refuses_others(backend):
    a = np.random.default_rng(9).random((33, 20, 3)).astype(np.float32)
    bands = pyr.laplacian(a, 3, synthesis="nearest", border="mirror", backend=backend)
    assert (bands.synthesis, bands.border) == ("nearest", "mirror")
    np.testing.assert_allclose(pyr.collapse(bands, backend=backend), a, rtol=0, atol=1e-5)
    np.testing.assert_allclose(pyr.collapse(bands, synthesis="h_nearest ⊗↑ g", border="mirror", backend=backend), a,
                               rtol=0, atol=1e-5)
    with pytest.raises(ValueError, match="the bands were made with synthesis 'nearest'; collapsing with 'doosabin'"):
        pyr.collapse(bands, synthesis="doosabin", backend=backend)
    with pytest.raises(ValueError, match="the bands were made with border 'mirror'; collapsing with 'clamp'"):
        pyr.collapse(bands, border="clamp", backend=backend)
    plain = list(bands)  # a plain list cannot say: the defaults, unchecked (a wrong image, as documented)
    assert np.abs(pyr.collapse(plain, backend=backend) - a).max() > 0.01
    np.testing.assert_allclose(pyr.collapse(plain, synthesis="nearest", border="mirror", backend=backend), a,
                               rtol=0, atol=1e-5)


def test_write_and_read_an_array_round_trip(tmp_path):
    a = np.random.default_rng(6).random((5, 7, 3)).astype(np.float32)
    pyr.write_image(tmp_path / "a.exr", a, pixel_type="float")
    back = pyr.read_image(tmp_path / "a.exr")
    np.testing.assert_array_equal(back.pixels, a)
    assert back.spec.channel_names == ["R", "G", "B"]


def test_process_files_runs_the_cli_pipeline(tmp_path):
    a = np.random.default_rng(7).random((9, 11, 3)).astype(np.float32)
    pyr.write_image(tmp_path / "in.exr", a, pixel_type="float")
    report = pyr.process_files(pyr.Blur(levels=2), [str(tmp_path / "in.exr")], str(tmp_path / "sub" / "out.exr"),
                               backend="cpu")
    assert report.exit_code == 0 and not report.failed and not report.skipped
    assert [job.output for job in report.done] == [str(tmp_path / "sub" / "out.exr")]
    np.testing.assert_allclose(pyr.read_image(tmp_path / "sub" / "out.exr").pixels,
                               pyramids.blur_reference(a.astype(np.float64), 2), rtol=0, atol=1e-5)


def test_process_files_takes_a_memory_budget_for_a_batch(tmp_path):
    """``memory=`` as ``--memory``: a batch within it (a picture too large to be held beside the others runs alone,
    streamed) writes what it writes without; a size it cannot read is refused."""
    rng = np.random.default_rng(9)
    for k, shape in enumerate([(8, 6, 3), (260, 300, 3)]):
        pyr.write_image(tmp_path / f"in{k}.exr", rng.random(shape).astype(np.float32), pixel_type="float")
    inputs = [str(tmp_path / "in0.exr"), str(tmp_path / "in1.exr")]
    for memory, folder in (("1M", "tight"), (None, "free")):
        report = pyr.process_files(pyr.Blur(levels=2), inputs, template=str(tmp_path / folder / "{stem}.exr"),
                                   backend="cpu", memory=memory)
        assert len(report.done) == 2 and report.exit_code == 0
    for k in range(2):
        assert (tmp_path / "tight" / f"in{k}.exr").read_bytes() == (tmp_path / "free" / f"in{k}.exr").read_bytes()
    with pytest.raises(UsageError, match="--memory: expected a size"):
        pyr.process_files(pyr.Blur(levels=2), inputs, template=str(tmp_path / "x" / "{stem}.exr"), memory="lots")


def test_docstring_examples_run():
    result = doctest.testmod(api, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 8 and result.failed == 0
    from pyramid_cli.exec import session

    assert doctest.testmod(session).failed == 0


def test_write_like_a_source_keeps_its_encoding(tmp_path):
    src = np.random.default_rng(8).random((6, 5, 3)).astype(np.float32)
    pyr.write_image(tmp_path / "src.png", src, pixel_type="uint8")
    img = pyr.read_image(tmp_path / "src.png")
    pyr.write_image(tmp_path / "out.png", pyr.blur(img.pixels, 1, backend="cpu"), like=img)
    out = pyr.read_image(tmp_path / "out.png")
    assert out.spec.pixel_type == "uint8" and out.spec.colorspace == "srgb"
    with pytest.raises(ValueError, match="1 channel"):
        pyr.write_image(tmp_path / "bad.png", np.ones((2, 2)), like=img)


def test_colour_spaces_pass_through_the_api(tmp_path):
    """``colorspace=``, ``tocolorspace=`` and ``colorconfig=`` (issue 25) reach the imageio layer."""
    import OpenImageIO as oiio

    from helpers.colour import ocio, studio_config
    from helpers.images import write

    px = np.random.default_rng(3).random((8, 8, 3)).astype(np.float32)
    src = write(tmp_path / "cct.exr", px, "float", oiio__ColorSpace="ACEScct")
    img = pyr.read_image(src)
    assert (img.spec.colorspace, img.spec.linear_space) == ("ACEScct", "ACEScg")
    assert np.allclose(img.pixels, ocio(px, "ACEScct", "ACEScg"), atol=1e-6)
    pyr.write_image(tmp_path / "g22.exr", img, tocolorspace="g22_rec709")
    got = oiio.ImageInput.open(str(tmp_path / "g22.exr"))
    assert got.spec().get_string_attribute("oiio:ColorSpace") == "g22_rec709_scene"
    config = str(studio_config(tmp_path))
    as_log = pyr.read_image(src, colorspace="plate_log", colorconfig=config)
    assert as_log.spec.linear_space == "plate_lin"
    from pyramid_cli.core.parse import parse

    assert pyr.process_files(pyr.Filter(expr=parse("[1] * g")), [str(src)], str(tmp_path / "o.exr"),
                             backend="cpu", colorconfig=config, colorspace="plate_log",
                             tocolorspace="plate_lin").exit_code == 0
