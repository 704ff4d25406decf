"""``pyramid diff --junit`` (pyramid_cli.diff.junit): one testcase per pair, valid against the JUnit 10 schema."""

from __future__ import annotations

import os

import pytest

from helpers.cli import invoke
from helpers.golden_tree import img
from helpers.images import write
from helpers.paths import DATA
from pyramid_cli.cli.diff import diff


def run(*args) -> object:
    return invoke(*args, command=diff)


def test_junit_validates_and_has_one_testcase_per_pair(tree, tmp_path):
    xmlschema = pytest.importorskip("xmlschema")
    out, gold = tree
    report = tmp_path / "r" / "junit.xml"
    report.parent.mkdir()
    assert run("--junit", report, out, gold).exit_code == 2
    schema = xmlschema.XMLSchema(str(DATA / "junit-10.xsd"))
    schema.validate(str(report))
    import xml.etree.ElementTree as ET

    root = ET.parse(report).getroot()
    cases = {tc.get("name"): tc for tc in root.iter("testcase")}
    assert set(cases) == {"pass.exr", "fail.exr", "new.exr", "gone.exr", os.path.join("sub", "alt.exr")}
    fail = cases["fail.exr"].find("failure")
    assert fail is not None and fail.get("type") == "failure" and "max error" in fail.text
    assert "RMS error" in fail.text and "PSNR" in fail.text
    assert cases["new.exr"].find("failure").get("type") == "missing"
    assert cases["pass.exr"].find("failure") is None
    suite = root.find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("5", "3", "0")



def test_junit_error_for_unreadable_file(tmp_path):
    xmlschema = pytest.importorskip("xmlschema")
    a = write(tmp_path / "a.exr", img(1))
    (tmp_path / "b.exr").write_bytes(b"broken")
    report = tmp_path / "j.xml"
    assert run("--junit", report, a, tmp_path / "b.exr").exit_code == 4
    xmlschema.XMLSchema(str(DATA / "junit-10.xsd")).validate(str(report))
    assert "<error" in report.read_text()

