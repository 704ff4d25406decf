"""Files shipped inside the package, read through its loader (:mod:`pyramid_cli.core.resources`)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import pyramid_cli.plan as plan_package
from pyramid_cli.core import resources


def test_a_shipped_file_reads_as_it_is_on_disk():
    folder = Path(plan_package.__file__).parent
    on_disk = (folder / "cost_model.json").read_text(encoding="utf-8")
    assert resources.text("pyramid_cli.plan", "cost_model.json") == on_disk
    assert resources.json_file("pyramid_cli.plan", "cost_model.json") == json.loads(on_disk)


def test_the_shader_templates_read_as_text():
    text = resources.text("pyramid_cli.exec.gl", "fullscreen.vert.glsl")
    assert text.lstrip().startswith("#version")


def test_a_file_that_is_not_shipped_is_not_found():
    with pytest.raises(FileNotFoundError):
        resources.text("pyramid_cli.plan", "no-such-file.json")
