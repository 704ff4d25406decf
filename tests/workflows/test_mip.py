"""MIP levels' sizes and options (pyramid_cli.workflows.mip).

Domain-true resampling against the float64 reference: tests/plan/test_resample.py; the files a renderer reads,
checked by maketx and OpenImageIO's TextureSystem: tests/system/test_maketx.py, tests/system/test_texture_system.py.
"""

from pyramid_cli.core.geometry import mip_levels, mip_sizes
from pyramid_cli.workflows.mip import parse_wrap


def test_levels_halve_down_to_one_pixel_like_maketx():
    assert mip_sizes((5, 3)) == [(5, 3), (2, 1), (1, 1)]
    sizes = mip_sizes((777, 1001))
    assert sizes[-1] == (1, 1) and len(sizes) == mip_levels((777, 1001))


def test_wrap_modes_default_to_both_axes():
    assert parse_wrap(None) is None
    assert parse_wrap("periodic") == ("periodic", "periodic")
