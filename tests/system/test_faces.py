"""The command line and the Python API warn and refuse alike.

Each rule lives in the job (:mod:`pyramid_cli.jobs.work`) or in the pipeline both faces call
(:func:`pyramid_cli.run.pipeline.process`), not in a command body: ``pyramid blur`` and ``pyr.blur``
refuse --quasi with --sigma and a bad sigma in the same words and warn of a mixed lattice in the same
words; ``pyramid blur --sigma`` and ``pyr.process_files`` say the sigma's blend alike; a TIFF texture's
tile that is not a multiple of 16 is refused by ``pyramid mipmap`` and the pipeline alike.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import pyramid_cli as pyr
from pyramid_cli.cli import main
from pyramid_cli.core.errors import MixedLatticeWarning, UsageError
from pyramid_cli.jobs.work import SigmaBlur, blur_work

pytestmark = pytest.mark.cli

MIXED = ("quadratic", "cubic")  # a dual ⊗↓ and a primal ⊗↑


def _cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _said(stderr: str, kind: str) -> list[str]:
    """The texts of the ``pyramid: KIND: …`` lines of a run's standard error."""
    prefix = f"pyramid: {kind}: "
    return [line[len(prefix):] for line in stderr.splitlines() if line.startswith(prefix)]


@pytest.fixture
def image(tmp_path):
    path = tmp_path / "in.exr"
    pyr.write_image(str(path), np.random.default_rng(0).random((16, 16, 3)).astype(np.float32))
    return path


@pytest.mark.parametrize(("kw", "args"), [
    ({"sigma": 2.0, "quasi": True}, ["--sigma", "2", "--quasi"]),  # the API raised "quasi and sigma …" before
    ({"sigma": -1.0}, ["--sigma", "-1"]),
    ({"sigma": float("inf")}, ["--sigma", "inf"]),
    ({"sigma": 1e6}, ["--sigma", "1e6"]),
])
def test_blur_refuses_alike(image, tmp_path, kw, args):
    r = _cli("blur", "--backend", "cpu", *args, image, tmp_path / "o.exr")
    assert r.exit_code == 2, r.output
    with pytest.raises(UsageError) as info:
        pyr.blur(np.ones((16, 16)), backend="cpu", **kw)
    assert _said(r.stderr, "error") == [str(info.value)]
    assert not (tmp_path / "o.exr").exists()


def test_quasi_with_sigma_is_refused_by_the_job_itself():
    with pytest.raises(UsageError, match="^--quasi and --sigma cannot be combined$"):
        blur_work(4, sigma=2.0, quasi=True)
    with pytest.raises(UsageError, match="^--sigma must be a positive finite number"):
        SigmaBlur(sigma=0.0)


def test_blur_warns_of_a_mixed_lattice_alike(image, tmp_path):
    r = _cli("blur", "--backend", "cpu", "--levels", "3", "--analysis", MIXED[0], "--synthesis", MIXED[1], image,
             tmp_path / "o.exr")
    assert r.exit_code == 0, r.output
    with pytest.warns(MixedLatticeWarning) as caught:
        pyr.blur(np.ones((16, 16)), 3, analysis=MIXED[0], synthesis=MIXED[1], backend="cpu")
    assert _said(r.stderr, "warning") == [str(w.message) for w in caught]


def test_the_sigma_blend_is_said_alike(image, tmp_path, caplog):
    r = _cli("blur", "--backend", "cpu", "--sigma", "2.5", image, tmp_path / "o.exr")
    assert r.exit_code == 0, r.output
    said = [line for line in r.stderr.splitlines() if line.startswith("pyramid: sigma 2.5: ")]
    assert len(said) == 1 and "standard deviation 2.5 px" in said[0], r.stderr
    assert said == [f"pyramid: {note}" for note in SigmaBlur(sigma=2.5).notes()]
    with caplog.at_level("INFO", logger="pyramid_cli"):  # the API logs what the command line says
        report = pyr.process_files(SigmaBlur(sigma=2.5), [str(image)], str(tmp_path / "p.exr"), backend="cpu",
                                   quiet=False)
    assert report.exit_code == 0
    assert said[0] in [f"pyramid: {r.getMessage()}" for r in caplog.records if r.name == "pyramid_cli"]
    assert "sigma" not in _cli("blur", "--backend", "cpu", "-q", "--sigma", "2.5", image, tmp_path / "o.exr").stderr


def test_a_tiff_tile_that_is_not_a_multiple_of_16_is_refused_alike(image, tmp_path):
    from pyramid_cli.exec.session import Session
    from pyramid_cli.jobs.texture import TextureLevels
    from pyramid_cli.run.pipeline import process

    r = _cli("mipmap", "--backend", "cpu", "--tile", "24", image, tmp_path / "o.tx")
    assert r.exit_code == 2, r.output
    with Session("cpu") as session, pytest.raises(UsageError) as info:
        process([str(image), str(tmp_path / "o.tx")], None, TextureLevels(levels=None), session, mip_tile=24)
    assert _said(r.stderr, "error") == [str(info.value)] == ["--tile 24: TIFF tiles must be a multiple of 16 "
                                                             f"({tmp_path / 'o.tx'})"]
    assert not (tmp_path / "o.tx").exists()
