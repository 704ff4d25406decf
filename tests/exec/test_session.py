"""Session: what each backend name means, how auto decides (by estimated cost, no context opened to
decide), and nothing run behind the user's back."""

from __future__ import annotations

import numpy as np
import pytest

from pyramid_cli.core.errors import BackendError, DataError
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import auto, session
from pyramid_cli.exec.gl import context
from pyramid_cli.exec.session import LoadingCPU, Session, is_software_renderer
from pyramid_cli.jobs.work import Blur, Filter
from pyramid_cli.plan.backend_cost import Estimate
from pyramid_cli.reference import filters as reference

LLVMPIPE = {"ok": True, "vendor": "Mesa", "renderer": "llvmpipe (LLVM 15.0.6, 256 bits)",
            "version": "4.5 (Core Profile) Mesa 22.3.6", "version_code": 450, "max_texture_size": 16384}


@pytest.fixture
def contexts(monkeypatch, tmp_path):
    """A private cache folder, a machine whose cached GL is llvmpipe, and a count of the EGL contexts made
    (none may be, unless a test runs on GL)."""
    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    made = []

    def create():
        made.append(1)
        raise BackendError("no OpenGL context through EGL (a test); use --backend cpu")

    monkeypatch.setattr(context, "create_context", create)
    monkeypatch.setattr("pyramid_cli.exec.gl.executor.create_context", create)
    monkeypatch.setattr(context, "machine_gl", lambda refresh=False, key=None: dict(LLVMPIPE))
    return made


def costs_say(monkeypatch, cpu: float, gl: float) -> None:
    """A fake cost model: every job takes ``cpu`` seconds on the CPU executor and ``gl`` on GL."""
    def estimates(cpu_plan, gl_plan, channels, **kw):
        return {"cpu": Estimate("cpu", cpu, 0.0, 0.0), "gl": Estimate("gl", gl, 0.0, 0.0)}

    monkeypatch.setattr(auto, "estimates", estimates)


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


def test_auto_picks_the_backend_the_model_says_finishes_first(contexts, monkeypatch):
    costs_say(monkeypatch, cpu=2.0, gl=1.0)
    with Session("auto") as s:
        s.decide(Blur(levels=5), [(1080, 1920, 4)])
        assert s.on_gl and s.name == "gl (llvmpipe (LLVM 15.0.6, 256 bits))"
    costs_say(monkeypatch, cpu=1.0, gl=2.0)
    with Session("auto") as s:
        s.decide(Blur(levels=5), [(1080, 1920, 4)])
        assert not s.on_gl and s.name.startswith("cpu (numba") and isinstance(s.executor, LoadingCPU)
    assert contexts == []  # deciding opened no context


def test_auto_on_gl_has_the_cpu_kernels_built_ahead_when_the_session_closes(contexts, monkeypatch):
    """Next time, the CPU executor is weighed without numba's import: its kernels are built ahead of time."""
    from pyramid_cli.exec.cpu import executor

    asked, said = [], []
    monkeypatch.setattr(executor, "build_ahead", lambda plan: asked.append(plan) or 2)
    costs_say(monkeypatch, cpu=2.0, gl=1.0)
    with Session("auto", note=said.append) as s:
        s.decide(Blur(levels=5), [(1080, 1920, 4)])
        assert s.on_gl and asked == []  # not while the run runs
    assert asked == [Blur(levels=5).plan([(1080, 1920)], "fused")]  # the CPU plan (fused), not GL's
    assert said[-1].startswith("2 CPU kernel(s) now build ahead of time in a process of its own")  # -v says so
    costs_say(monkeypatch, cpu=1.0, gl=2.0)
    with Session("auto") as s:
        s.decide(Blur(levels=5), [(1080, 1920, 4)])
    assert len(asked) == 1  # the CPU executor ran: it builds what it ran through numba itself


def test_auto_decides_once_at_the_first_job_and_never_on_the_reference(contexts, monkeypatch):
    costs_say(monkeypatch, cpu=1.0, gl=2.0)
    with Session("auto") as s:
        assert not s.decided
        (out,) = s.run(Blur(levels=1), np.ones((4, 4, 3), dtype=np.float32))
        assert s.decided and s.ran.startswith("cpu") and s.executor is not None
        costs_say(monkeypatch, cpu=2.0, gl=1.0)  # a later job does not move the session
        s.decide(Blur(levels=1), [(4, 4)])
        assert not s.on_gl
    np.testing.assert_allclose(out, 1.0, atol=1e-6)
    assert contexts == []


def test_the_verbose_line_gives_each_estimate_and_the_choice(contexts, monkeypatch):
    costs_say(monkeypatch, cpu=1.92, gl=1.31)
    lines = []
    with Session("auto", note=lines.append) as s:
        s.decide(Blur(levels=5), [(1080, 1920, 4)])
    assert lines == ["executor gl (llvmpipe (LLVM 15.0.6, 256 bits)) (auto: cpu 1.92 s, "
                     "gl (llvmpipe (LLVM 15.0.6, 256 bits)) 1.31 s (est.) → gl)"]
    with Session("cpu", note=lines.append):
        assert lines[-1].startswith("executor cpu (numba") and lines[-1].endswith("(asked for)")


def test_real_estimates_for_a_job_and_a_batch(contexts):
    """The shipped model, no fake: both backends estimated, seconds grow with the batch, the choice is the
    smaller; no context opened and numba not needed to decide."""
    with Session("auto") as one, Session("auto") as many:
        one.decide(Blur(levels=5), [(1080, 1920, 4)], dtype=np.float16)
        many.decide(Blur(levels=5), [(1080, 1920, 4)], count=50, dtype=np.float16)
        for s in (one, many):
            assert set(s.estimates) == {"cpu", "gl"}
            best = min(s.estimates, key=lambda b: s.estimates[b].seconds)
            assert s.on_gl == (best == "gl") and s.why.endswith(f"→ {best}")
        for b in ("cpu", "gl"):
            assert many.estimates[b].seconds > one.estimates[b].seconds > 0
    assert contexts == []


def test_no_gl_here_runs_on_the_cpu_with_one_warning(monkeypatch, tmp_path):
    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(context, "machine_gl", lambda refresh=False, key=None: {
        "ok": False, "reason": "no OpenGL context through EGL (libEGL.so.1 missing); use --backend cpu"})
    warnings = []
    with Session("auto", warn=warnings.append) as s:
        (out,) = s.run(Blur(levels=1), np.ones((4, 4)))
        assert s.ran.startswith("cpu") and s.why.startswith("auto: no GL here (")
    assert warnings == ["no OpenGL context through EGL (libEGL.so.1 missing); use --backend cpu; running on the CPU"]
    np.testing.assert_allclose(out, 1.0, atol=1e-6)


def test_a_context_that_fails_where_the_cache_said_one_opens_falls_back_and_forgets(contexts, monkeypatch, tmp_path):
    costs_say(monkeypatch, cpu=2.0, gl=1.0)
    forgotten = []
    monkeypatch.setattr(context, "forget", lambda key=None: forgotten.append(1))
    warnings = []
    with Session("auto", warn=warnings.append) as s:
        s.decide(Blur(levels=1), [(4, 4)])
        (out,) = s.run(Blur(levels=1), np.ones((4, 4)))
        assert s.ran.startswith("cpu") and forgotten == [1] and len(contexts) == 1
    assert warnings and warnings[0].endswith("; running on the CPU")
    np.testing.assert_allclose(out, 1.0, atol=1e-6)


def test_an_uncalibrated_hardware_gpu_keeps_gl(contexts, monkeypatch):
    gpu = {**LLVMPIPE, "renderer": "NVIDIA H100 80GB HBM3/PCIe/SSE2"}
    monkeypatch.setattr(context, "machine_gl", lambda refresh=False, key=None: gpu)
    with Session("auto") as s:
        s.decide(Blur(levels=5), [(64, 64)])
        assert s.on_gl and "not calibrated here" in s.why
    assert contexts == []


def test_prepare_async_loads_the_cpu_executor_in_the_background(contexts, monkeypatch):
    costs_say(monkeypatch, cpu=1.0, gl=2.0)
    monkeypatch.setattr(session, "spare_core", lambda: True)
    with Session("auto") as s:
        s.prepare_async(Blur(levels=2), [(16, 16, 3)], dtype=np.float32)
        ex = s.executor
        assert isinstance(ex, LoadingCPU) and ex.started
        assert ex.strategy == "fused" and ex.texture_bytes((5, 5)) == 0 and not ex.host_textures  # no waiting
        (out,) = s.run(Blur(levels=2), np.ones((16, 16, 3), dtype=np.float32))  # waits for the thread
        assert ex.result().backend == "cpu" and s.ran.startswith("cpu")
    np.testing.assert_allclose(out, 1.0, atol=1e-6)


def test_prepare_async_waits_on_a_busy_machine(contexts, monkeypatch):
    costs_say(monkeypatch, cpu=1.0, gl=2.0)
    monkeypatch.setattr(session, "spare_core", lambda: False)
    with Session("auto") as s:
        s.prepare_async(Blur(levels=2), [(16, 16, 3)], dtype=np.float32)
        assert s.decided and not s.executor.started  # made when first used


def test_prepare_async_never_fails(contexts, monkeypatch):
    costs_say(monkeypatch, cpu=1.0, gl=2.0)

    class Broken(Blur):
        def plan(self, sizes, strategy="cost"):
            raise RuntimeError("no plan")

    with Session("auto") as s:
        s.prepare_async(Broken(levels=1), [(4, 4)])
        assert s.decided


@pytest.mark.gl
def test_auto_moves_an_image_gl_cannot_hold_to_the_cpu_with_one_warning(gl_executor, monkeypatch):
    costs_say(monkeypatch, cpu=2.0, gl=1.0)  # auto keeps GL, as on a GPU
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


def test_cpu_backend_without_numba_is_refused_at_once(monkeypatch):
    monkeypatch.setattr(session, "_numba_installed", lambda: False)
    monkeypatch.setattr(session, "_compiled_cpu", lambda threads: None)
    from pyramid_cli.exec import cpu

    monkeypatch.setattr(cpu, "available", lambda: (False, "numba cannot be imported (a test); install numba"))
    with pytest.raises(BackendError, match="numba cannot be imported"):
        Session("cpu")


def test_a_broken_cost_model_falls_back_to_the_renderer_rule(contexts, monkeypatch):
    def broken(*a, **k):
        raise ValueError("backend_costs.json: missing 'cpu'")

    monkeypatch.setattr(auto, "estimates", broken)
    with Session("auto") as s:
        s.decide(Blur(levels=2), [(8, 8)])
        assert not s.on_gl and "no estimate (ValueError" in s.why
    assert contexts == []


def test_float64_outputs_are_computed_in_float64_on_every_backend_but_gl():
    from pyramid_cli.jobs.work import Levels
    from pyramid_cli.reference import pyramids

    a = np.random.default_rng(3).random((11, 9, 2))
    want = pyramids.blur_reference(a, 2)
    with Session("reference") as s:
        np.testing.assert_array_equal(s.run(Blur(levels=2), [a], np.float64)[0], want)
    for backend in ("cpu", "auto"):  # the compiled CPU executor's float64 kernels (auto: whatever it decides)
        with Session(backend) as s:
            (got,) = s.run(Blur(levels=2), [a], np.float64)
            assert got.dtype == np.float64 and s.ran.startswith("cpu (numba")
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)  # float32 would be ~1e-7 off
            kept, *levels = s.run(Levels(levels=2), [a], np.float64)
            assert kept is a and [lv.dtype for lv in levels] == [np.float64] * 2


def test_a_sessions_own_warnings_are_backend_warnings_at_the_callers_line(monkeypatch, tmp_path):
    from pyramid_cli.core.errors import BackendWarning

    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(context, "machine_gl", lambda refresh=False, key=None: {"ok": False, "reason": "no EGL"})
    with pytest.warns(BackendWarning, match="^no EGL; running on the CPU$") as caught, Session("auto") as s:
        s.run(Blur(levels=1), np.ones((4, 4)))
    assert caught[0].filename == __file__
