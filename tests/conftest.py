"""Fixtures every test folder shares: the executors.

One executor of each kind per session: ``gl`` (an OpenGL context through EGL, checked for ``GL_NO_ERROR``
before and after each test), ``cpu_executor`` (the compiled CPU executor, numba kernels cached in one folder
per user kept across runs), ``emulator_executor`` (the plan emulator, numpy float64). ``executor`` runs a test
once per kind (see ``EXECUTORS``): adding an executor to every conformance test (tests/exec/test_conformance.py)
is adding it there.

Without an EGL context the GL tests skip with the reason, except under CI (the
environment variable ``CI`` set), where GL must run and they fail instead.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from pyramid_cli.core.errors import BackendError

# No ahead-of-time kernel builders behind the tests' runs (a process each, seconds of compiling, after every run
# that loads a new kernel through numba), and none of a machine's built modules in their way: the tests of
# pyramid_cli.exec.cpu.aot turn them on where they test them (tests/exec/cpu/test_aot.py).
os.environ["PYRAMID_AOT"] = "0"


@pytest.fixture(scope="session")
def gl_executor():
    from pyramid_cli.exec.gl import GLExecutor

    executor = GLExecutor()
    try:
        executor.open()
    except BackendError as e:
        if os.environ.get("CI"):
            pytest.fail(f"CI must run the GL tests: {e.message}")
        pytest.skip(e.message)
    yield executor
    executor.close()


@pytest.fixture
def gl(gl_executor):
    """The session's executor, with ``ctx.error`` checked before and after the test."""
    assert gl_executor.error == "GL_NO_ERROR"
    yield gl_executor
    assert gl_executor.error == "GL_NO_ERROR"


def cpu_cache_folder() -> Path:
    """The kernel cache the tests share: one folder per user, kept across runs, so a rerun loads instead of
    compiling (every pass shape compiles once, about a second each on 2 cores)."""
    folder = Path(tempfile.gettempdir()) / f"pyramid-cpu-test-cache-{os.getuid()}"
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(scope="session")
def cpu_executor():
    """The compiled CPU executor (two threads), its kernels in :func:`cpu_cache_folder`; skipped without numba."""
    pytest.importorskip("numba")
    from pyramid_cli.exec import cpu

    with cpu.CPUExecutor(threads=2, cache=cpu_cache_folder()) as executor:
        yield executor


class Emulator:
    """The plan emulator (:mod:`pyramid_cli.exec.emulate`) behind the executor interface, in float64 throughout:
    what the others are held to, so it is held to the reference to 1e-9."""

    strategy = "cost"

    def run(self, plan, images) -> np.ndarray:
        return self.run_outputs(plan, images)[-1]

    def run_outputs(self, plan, images) -> list[np.ndarray]:
        from pyramid_cli.exec import emulate

        return emulate.run_outputs(plan, [images] if isinstance(images, np.ndarray) else list(images))


@pytest.fixture(scope="session")
def emulator_executor():
    return Emulator()


@dataclass(frozen=True)
class Subject:
    """One executor under the conformance suite: the object, the pixel type it computes in and its tolerance
    against the float64 reference."""

    name: str
    executor: object
    dtype: type
    atol: float

    def __getattr__(self, name):
        return getattr(self.executor, name)  # run, run_outputs, prepare…: the executor's own

    def pixels(self, array: np.ndarray) -> np.ndarray:
        """``array`` in the type this executor is fed and returns."""
        return array.astype(self.dtype)


#: Every executor: (the fixture that makes it, the pixel type it computes in, its tolerance, pytest marks).
EXECUTORS = {
    "emulator": ("emulator_executor", np.float64, 1e-9, ()),
    "cpu": ("cpu_executor", np.float32, 1e-5, ()),
    "gl": ("gl", np.float32, 1e-5, (pytest.mark.gl,)),
}
#: The executors computing in float32 (half inputs and outputs, float32 results).
FLOAT32 = [name for name, (_, dtype, _, _) in EXECUTORS.items() if dtype == np.float32]


def _params(names):
    return [pytest.param(name, marks=EXECUTORS[name][3], id=name) for name in names]


@pytest.fixture(params=_params(EXECUTORS))
def executor(request) -> Subject:
    """Each executor in turn (:data:`EXECUTORS`)."""
    fixture, dtype, atol, _ = EXECUTORS[request.param]
    return Subject(request.param, request.getfixturevalue(fixture), dtype, atol)


@pytest.fixture(params=_params(FLOAT32))
def float32_executor(request) -> Subject:
    """Each executor computing in float32 in turn (half inputs and outputs are theirs)."""
    fixture, dtype, atol, _ = EXECUTORS[request.param]
    return Subject(request.param, request.getfixturevalue(fixture), dtype, atol)


#: The longest tests (half a minute and more each on 2 cores), started first: spread over pytest-xdist's
#: workers (`make test`), one of them starting last would be the run's tail.
LONGEST_FIRST = ("tests/system/test_memory_cgroup.py", "tests/system/test_docs.py", "tests/system/test_bench_peers.py",
                 "tests/system/test_viewers_osd.py", "tests/system/test_bench_tiles.py")


def pytest_collection_modifyitems(config, items):  # noqa: ARG001 - pytest's hook signature
    items.sort(key=lambda item: not item.nodeid.startswith(LONGEST_FIRST))  # stable: the rest keep their order
