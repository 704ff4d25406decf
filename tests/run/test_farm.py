"""Open Job Description templates (pyramid_cli.run.farm); validated and run by openjd: tests/system/test_openjd.py."""

from pyramid_cli.run import farm


def test_frame_ranges_in_openjd_s_spelling():
    assert farm.openjd_range("1-10x2") == "1-9:2"
    assert farm.openjd_range("1,3,5-7") == "1-5:2,6,7"
