"""The ``pyramid`` command, run the two ways the tests run it: in process (click's CliRunner) and as a subprocess."""

from __future__ import annotations

import subprocess
import sys

from click.testing import CliRunner, Result

#: The command line of ``pyramid`` as a subprocess (the module, so the checkout's code runs).
CLI = [sys.executable, "-m", "pyramid_cli.cli"]
#: Seconds a subprocess may run before the test fails instead of hanging.
TIMEOUT = 300


def invoke(*args, command=None) -> Result:
    """Run ``pyramid ARGS…`` (or ``command`` ARGS…, a click command) in process; every argument is passed as ``str``."""
    if command is None:
        from pyramid_cli.cli import main

        command = main
    return CliRunner().invoke(command, [str(a) for a in args])


def run_cli(*args, timeout: float = TIMEOUT, **kw) -> subprocess.CompletedProcess:
    """Run ``pyramid ARGS…`` in a subprocess, its output captured as text."""
    return subprocess.run(CLI + [str(a) for a in args], capture_output=True, text=True, timeout=timeout, **kw)


def peak_rss(args) -> int:
    """Peak resident set of one child process running ``args``, in bytes (ru_maxrss of the waited-for child,
    Linux: KiB).

    Run through a fresh Python so that RUSAGE_CHILDREN covers exactly that child."""
    code = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, r.returncode); "
            "sys.stderr.write(r.stderr)")
    r = subprocess.run([sys.executable, "-c", code] + [str(a) for a in args], capture_output=True, text=True,
                       timeout=TIMEOUT)
    kib, rc = r.stdout.split()
    assert rc == "0", r.stderr
    return int(kib) * 1024
