"""The EGL context (``pyramid_cli.exec.gl.context``): without one, a backend error that names the fix."""

from functools import cache

import numpy as np
import pytest

from pyramid_cli.core.errors import BackendError
from pyramid_cli.core.parse import parse
from pyramid_cli.plan import plan


@cache
def planned(text: str, size: tuple[int, int], strategy: str = "cost"):
    return parse(text), plan(parse(text), size, strategy)


def test_no_context_is_a_backend_error_naming_the_fix(monkeypatch):
    import moderngl

    from pyramid_cli.exec import gl as glmod

    def refuse(*args, **kwargs):
        raise Exception("libEGL.so.1: cannot open shared object file")

    monkeypatch.setattr(moderngl, "create_standalone_context", refuse)
    ok, why = glmod.available()
    assert not ok and "libEGL.so.1" in why and "apt-get install -y libegl1" in why and "--backend cpu" in why
    assert "\n" not in why
    with pytest.raises(BackendError, match="--backend cpu"):
        glmod.GLExecutor().run(planned("g", (1, 1))[1], np.zeros((1, 1), dtype=np.float32))
