"""JUnit XML for ``pyramid diff --junit``: one testcase per pair, as CI systems read it.

The layout follows the schema Jenkins (and GitLab, GitHub test reporters,
Surefire) accept, ``junit-10.xsd``: ``<testsuites>`` holding one
``<testsuite>`` whose ``<testcase>`` elements carry a ``<failure>`` (over the
thresholds, a warning, a size mismatch, a missing or extra golden) or an
``<error>`` (a file that cannot be read), with the statistics as text.
"""

from __future__ import annotations

import datetime as _dt
import os
import socket
import xml.etree.ElementTree as ET
from collections.abc import Sequence

from pyramid_cli.core.errors import OutputError
from pyramid_cli.diff.goldens import PairResult
from pyramid_cli.diff.idiff import format_value
from pyramid_cli.imageio.atomic import atomic_path

__all__ = ["junit_xml", "write_junit"]


def _details(pr: PairResult) -> str:
    lines = [f"A: {pr.path_a or '-'}", f"B: {pr.path_b or '-'}", f"status: {pr.status} (rule: {pr.rule})"]
    if len(pr.references) > 1:
        lines.append("accepted references: " + ", ".join(pr.references))
    for lv in pr.levels:
        r = lv.result
        where = f" @ (x={r.max_x}, y={r.max_y}, {r.max_channel_name})" if r.max_x is not None else ""
        lines.append(
            f"subimage {lv.subimage} MIP level {lv.miplevel} ({r.width}x{r.height}, {r.channels} channels): "
            f"max error {format_value(r.max_error)}{where}, mean error {format_value(r.mean_error)}, "
            f"RMS error {format_value(r.rms_error)}, PSNR {format_value(r.psnr)} dB, "
            f"{r.n_warn} pixels ({r.percent(r.n_warn):.3g}%) over warn {format_value(r.thresholds['warn'])}, "
            f"{r.n_fail} pixels ({r.percent(r.n_fail):.3g}%) over fail {format_value(r.thresholds['fail'])}"
            + (f", {r.n_nonfinite} NaN/Inf mismatches" if r.n_nonfinite else "")
            + (f", mean FLIP {lv.flip:.6g}" if lv.flip is not None else ""))
    return "\n".join(lines)


def junit_xml(results: Sequence[PairResult], *, suite: str = "pyramid diff") -> bytes:
    """The JUnit XML document for ``results``.

    Parameters
    ----------
    results : sequence of PairResult
    suite : str
        The testsuite's name.

    Returns
    -------
    bytes
        UTF-8 XML with its declaration.
    """
    failures = sum(1 for r in results if r.exit_code and r.status != "file")
    errors = sum(1 for r in results if r.status == "file")
    root = ET.Element("testsuites", name=suite, tests=str(len(results)), failures=str(failures),
                      errors=str(errors))
    ts = ET.SubElement(root, "testsuite", name=suite, tests=str(len(results)), failures=str(failures),
                       errors=str(errors), skipped="0", time="0",
                       timestamp=_dt.datetime.now().replace(microsecond=0).isoformat(),
                       hostname=socket.gethostname() or "localhost")
    for r in results:
        folder = os.path.dirname(r.name)
        classname = "pyramid.diff" + ("." + folder.replace(os.sep, ".") if folder else "")
        tc = ET.SubElement(ts, "testcase", name=r.name, classname=classname, time="0")
        details = _details(r)
        if r.status == "file":
            ET.SubElement(tc, "error", message=r.message, type="file").text = details
        elif r.exit_code:
            ET.SubElement(tc, "failure", message=f"{r.status.upper()}: {r.message}", type=r.status).text = details
        else:
            ET.SubElement(tc, "system-out").text = details
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def write_junit(path: str, results: Sequence[PairResult], *, suite: str = "pyramid diff") -> None:
    """Write :func:`junit_xml` to ``path`` atomically.

    Raises
    ------
    OutputError
        ``path`` cannot be written.
    """
    data = junit_xml(results, suite=suite)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OutputError(f"cannot write {path}: no such folder {folder}")
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data)
