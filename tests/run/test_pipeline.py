"""The batch runner's small rules (pyramid_cli.run.pipeline); whole runs: tests/run/test_batch.py, tests/system."""

import pytest

from pyramid_cli.core.errors import UsageError
from pyramid_cli.run import pipeline


def test_level_paths_need_a_level_field():
    assert pipeline.level_path("out_{level}.exr", 3) == "out_3.exr"
    with pytest.raises(UsageError, match="needs {level}"):
        pipeline.level_path("out.exr", 3)
