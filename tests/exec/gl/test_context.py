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


# ------------------------------------------------------------ the machine's GL, cached
@pytest.fixture
def probes(monkeypatch, tmp_path):
    """A private cache folder and a count of the probes (each would open a context)."""
    from pyramid_cli.exec.gl import context

    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    made = []

    def probe():
        made.append(1)
        return {"ok": True, "vendor": "Mesa", "renderer": "llvmpipe (a test)", "version": "4.5", "version_code": 450,
                "max_texture_size": 16384}

    monkeypatch.setattr(context, "probe", probe)
    return made


def test_the_renderer_is_probed_once_and_then_read_from_the_cache(probes):
    from pyramid_cli.exec.gl import context

    first = context.machine_gl(key="k1")
    assert context.machine_gl(key="k1") == first and first["renderer"] == "llvmpipe (a test)"
    assert len(probes) == 1
    context.machine_gl(key="k2")  # another driver: probed again
    assert len(probes) == 2
    context.machine_gl(key="k2", refresh=True)
    assert len(probes) == 3


@pytest.mark.parametrize("entry", [b"{not json", b'{"key": "k1"}', b'{"key": "k1", "gl": {"ok": true}}', b"[]",
                                   b'{"key": "k1", "gl": {"ok": false}}'])
def test_a_corrupt_cache_entry_is_probed_again(probes, entry):
    from pyramid_cli.core import cache
    from pyramid_cli.exec.gl import context

    assert cache.write(context.CACHE_FOLDER, context.CACHE_ENTRY.format(key="k1"), entry)
    assert context.machine_gl(key="k1")["ok"] and len(probes) == 1
    context.machine_gl(key="k1")
    assert len(probes) == 1  # and the entry it wrote is good


def test_no_gl_is_cached_with_its_reason(monkeypatch, tmp_path):
    import moderngl

    from pyramid_cli.exec.gl import context

    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    tries = []

    def refuse(*args, **kwargs):
        tries.append(1)
        raise Exception("libEGL.so.1: cannot open shared object file")

    monkeypatch.setattr(moderngl, "create_standalone_context", refuse)
    for _ in range(2):
        info = context.machine_gl(key="k")
        assert not info["ok"] and "libEGL.so.1" in info["reason"] and "--backend cpu" in info["reason"]
    assert len(tries) == 1
    context.forget("k")
    context.machine_gl(key="k")
    assert len(tries) == 2


def test_the_driver_key_follows_the_environment_and_the_vendor_files(monkeypatch, tmp_path):
    from pyramid_cli.exec.gl import context

    vendors = tmp_path / "egl_vendor.d"
    vendors.mkdir()
    icd = vendors / "10_test.json"
    icd.write_text('{"file_format_version": "1.0.0", "ICD": {"library_path": "libEGL_test.so.0"}}')
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_DIRS", str(vendors))
    keys = [context.driver_key()]
    assert context.driver_key() == keys[0]  # deterministic
    icd.write_text('{"file_format_version": "1.0.0", "ICD": {"library_path": "libEGL_other.so.0"}}')
    keys.append(context.driver_key())
    monkeypatch.setenv("MESA_LOADER_DRIVER_OVERRIDE", "zink")
    keys.append(context.driver_key())
    monkeypatch.setenv("LIBGL_ALWAYS_SOFTWARE", "1")
    keys.append(context.driver_key())
    monkeypatch.setenv("UNRELATED_SETTING", "1")
    keys.append(context.driver_key())
    assert len(set(keys)) == 4 and keys[-1] == keys[-2]
