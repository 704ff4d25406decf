"""The read and write settings of every command (pyramid_cli.run.settings)."""

from pyramid_cli.run.settings import ReadOptions, WriteOptions


def test_defaults_are_the_command_lines():
    assert ReadOptions() == ReadOptions(colorspace="auto", alpha="auto", nan="keep")
    assert WriteOptions() == WriteOptions(pixel_type=None, dither=False, compression=None, force=False)


def test_write_options_become_write_images_keywords_with_the_inputs():
    options = WriteOptions(pixel_type="half", dither=True, compression="zip", force=True).for_inputs(["a.exr", "b"])
    assert options == {"pixel_type": "half", "dither": True, "compression": "zip", "force": True,
                       "inputs": ("a.exr", "b")}
    assert WriteOptions().for_inputs(iter([]))["inputs"] == ()
