"""Session: what each backend name means, and nothing run behind the user's back."""

from __future__ import annotations

import numpy as np
import pytest

from pyramid_cli.core.errors import BackendError, DataError
from pyramid_cli.core.parse import parse
from pyramid_cli.exec.session import Session, is_software_renderer
from pyramid_cli.jobs.work import Blur, Filter
from pyramid_cli.reference import filters as reference


def test_reference_backend_runs_the_oracle_and_no_plan():
    x = np.random.default_rng(0).random((9, 7, 2))
    with Session("reference") as s:
        (out,) = s.run(Filter(expr=parse("gauss5"), border="wrap"), x)
        assert s.name == s.ran == "reference" and s.executor is None
        with pytest.raises(BackendError, match="runs jobs, not plans"):
            s.run_plan(Filter(expr=parse("gauss5")).plan([(9, 7)]), [x])
    assert out.dtype == np.float32
    from pyramid_cli.core.border import Border

    np.testing.assert_allclose(out, reference.run(parse("gauss5"), x, Border.WRAP), rtol=0, atol=1e-6)


def test_cpu_backend_runs_plans_on_the_cpu():
    with Session("cpu") as s:
        (out,) = s.run(Blur(levels=2), np.ones((5, 5)))
        assert s.ran.startswith("cpu") and not s.on_gl
    np.testing.assert_allclose(out, 1.0, atol=1e-6)


@pytest.mark.gl
def test_auto_moves_an_image_gl_cannot_hold_to_the_cpu_with_one_warning(gl_executor, monkeypatch):
    from pyramid_cli.exec import session

    monkeypatch.setattr(session, "is_software_renderer", lambda renderer: False)  # auto keeps GL, as on a GPU
    warnings = []
    with Session("auto", warn=warnings.append) as s:
        assert s.on_gl

        def too_big(*a, **k):
            raise DataError("image 0 needs a 16384x16384 texture")

        monkeypatch.setattr(s.executor, "run_outputs", too_big)
        (out,) = s.run(Blur(levels=1), np.ones((4, 4)))
        assert s.ran.startswith("cpu") and warnings == ["image 0 needs a 16384x16384 texture; running this image on "
                                                        "the CPU"]
    np.testing.assert_allclose(out, 1.0, atol=1e-6)


@pytest.mark.gl
def test_gl_backend_never_falls_back(gl_executor, monkeypatch):
    with Session("gl") as s:
        def too_big(*a, **k):
            raise DataError("too big")

        monkeypatch.setattr(s.executor, "run_outputs", too_big)
        with pytest.raises(DataError):
            s.run(Blur(levels=1), np.ones((4, 4)))


def test_software_renderers_are_recognised():
    assert is_software_renderer("llvmpipe (LLVM 15.0.6, 256 bits)")
    assert is_software_renderer("softpipe") and is_software_renderer("Software Rasterizer")
    assert not is_software_renderer("NVIDIA H100 80GB HBM3/PCIe/SSE2")


def test_unknown_names_are_refused():
    with pytest.raises(ValueError, match="backend must be one of auto, gl, cpu, reference, not 'vulkan'"):
        Session("vulkan")
    with pytest.raises(ValueError, match="precision must be one of"):
        Session("cpu", "double")


@pytest.mark.gl
def test_auto_prefers_the_compiled_cpu_executor_over_a_software_gl(gl_executor):
    with Session("auto") as s:
        if "llvmpipe" not in gl_executor.renderer and "softpipe" not in gl_executor.renderer:
            assert s.on_gl  # a hardware GPU keeps GL
        else:
            assert s.name.startswith("cpu (numba") and "software renderer" in s.why
