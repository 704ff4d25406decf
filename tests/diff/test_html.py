"""``pyramid diff --html`` (pyramid_cli.diff.html): a self-contained report, failures first, that a browser
shows and flips."""

from __future__ import annotations

import shutil
import subprocess
import tempfile

import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from pyramid_cli.cli.diff import diff


def run(*args) -> object:
    return invoke(*args, command=diff)


def test_html_report_self_contained_failures_first(tree, tmp_path):
    out, gold = tree
    rep = tmp_path / "rep"
    assert run("--html", rep, out, gold).exit_code == 2
    text = (rep / "index.html").read_text()
    assert "http://" not in text and "https://" not in text      # no network
    order = [text.index(f"</span> {n}</h2>") for n in ("fail.exr", "new.exr", "gone.exr", "pass.exr")]
    assert order[:1] == [min(order)] and order[-1] == max(order)   # failures first, passes last
    assert "class='flip'" in text and "data-b=" in text
    for src in set(__import__("re").findall(r"src='(img/[^']+)'", text)):
        assert (rep / src).is_file()
    assert "|A-B| colour" in text and "|A-B| alpha" in text
    assert "RMS" in text and "PSNR" in text



def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")



CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--no-first-run"]



@pytest.mark.cli
@pytest.mark.slow
@pytest.mark.skipif(_chromium() is None, reason="chromium is not on PATH (apt-get install -y chromium)")
def test_html_report_in_headless_chromium(tree, tmp_path):
    out, gold = tree
    rep = tmp_path / "rep"
    assert run("--html", rep, out, gold).exit_code == 2
    url = (rep / "index.html").as_uri()
    with tempfile.TemporaryDirectory() as profile:
        dom = subprocess.run([_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
                              "--enable-logging=stderr", "--v=0", "--virtual-time-budget=2000", "--dump-dom", url],
                             capture_output=True, text=True, timeout=60)
    assert "<section class=\"pair failure\"" in dom.stdout, dom.stderr[-2000:]
    assert "Uncaught" not in dom.stderr and "CONSOLE" not in dom.stderr, dom.stderr[-2000:]
    assert "data-showing=\"A\"" in dom.stdout
    with tempfile.TemporaryDirectory() as profile:   # the script runs: #B flips every picture to B
        dom_b = subprocess.run([_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
                                "--virtual-time-budget=2000", "--dump-dom", url + "#B"],
                               capture_output=True, text=True, timeout=60)
    assert "data-showing=\"B\"" in dom_b.stdout and "data-showing=\"A\"" not in dom_b.stdout
    assert "B (reference) \u2014 click to flip" in dom_b.stdout
    shot = tmp_path / "shot.png"
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([_chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--screenshot={shot}",
                        "--window-size=1200,900", url], capture_output=True, timeout=60)
    inp = oiio.ImageInput.open(str(shot))
    px = inp.read_image("uint8")
    inp.close()
    assert px.shape[:2] == (900, 1200) and px.std() > 5   # something was drawn

