"""Disks for the failure tests: a small or read-only tmpfs (root on Linux only), and the temporaries a run left."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys

import pytest


@contextlib.contextmanager
def mounted(path, options: str):
    """A tmpfs mounted at ``path`` (created) with mount ``options`` (``"size=64k"``, ``"ro,size=64k"``); skips
    where mounting needs a root this process is not, unmounts at the end."""
    if os.geteuid() != 0 or not sys.platform.startswith("linux"):
        pytest.skip("mounting a tmpfs needs root on Linux")
    path.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True)
    if r.returncode:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], check=False)


def leftovers(folder) -> list[str]:
    """The hidden temporaries (``.NAME.tmp-…``: files, staging folders) in ``folder``."""
    return [f for f in os.listdir(folder) if ".tmp-" in f]
