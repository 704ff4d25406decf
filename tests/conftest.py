"""GL fixtures: one executor per session; every GL test starts and ends with GL_NO_ERROR.

Without an EGL context the GL tests skip with the reason, except under CI (the
environment variable ``CI`` set), where GL must run and they fail instead.
"""

import os

import pytest

from pyramid_cli.core.errors import BackendError


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
