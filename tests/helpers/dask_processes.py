"""Real ``dask scheduler`` and ``dask worker`` processes for the cluster tests (not a LocalCluster).

:class:`DaskProcesses` starts them with the ``dask`` command beside the running Python,
each in its own process group, and kills every one of them on :meth:`close` whatever
happened (the tests' fixture calls it), so no test leaves a scheduler behind.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

DASK = str(Path(sys.executable).with_name("dask"))
STOP_S = 10  # seconds a stopped scheduler or worker may take to end before it is killed


def _wait_for(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what} within {timeout} s")
        time.sleep(0.05)


class DaskProcesses:
    """A scheduler on 127.0.0.1 writing ``folder/scheduler.json``, and worker processes joining it.

    Parameters
    ----------
    folder : Path
        Where the scheduler file and the processes' logs go.
    env : dict, optional
        Extra environment variables for the workers (test hooks).
    """

    def __init__(self, folder: Path, env: dict[str, str] | None = None):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.scheduler_file = self.folder / "scheduler.json"
        self.env = {**os.environ, **(env or {})}
        self.scheduler: subprocess.Popen | None = None
        self.workers: list[subprocess.Popen] = []

    def _start(self, name: str, args: list[str]) -> subprocess.Popen:
        log = open(self.folder / f"{name}.log", "ab")  # noqa: SIM115 - the process holds it
        try:
            return subprocess.Popen([DASK, *args], stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                    start_new_session=True)
        finally:
            log.close()

    def start_scheduler(self, timeout: float = 60) -> str:
        """Start the scheduler and return its address once its file is written."""
        self.scheduler = self._start("scheduler", ["scheduler", "--host", "127.0.0.1", "--port", "0",
                                                   "--scheduler-file", str(self.scheduler_file), "--no-dashboard"])
        _wait_for(self.scheduler_file.exists, timeout, "no scheduler file")
        _wait_for(lambda: bool(self.scheduler_file.read_text().strip()), timeout, "an empty scheduler file")
        return self.address

    @property
    def address(self) -> str:
        return json.loads(self.scheduler_file.read_text())["address"]

    def start_workers(self, n: int = 2, timeout: float = 60) -> None:
        """``dask worker --nworkers n --nthreads 1`` (one nanny process per worker), waiting until all joined."""
        self.workers.append(self._start(f"workers{len(self.workers)}", [
            "worker", "--nworkers", str(n), "--nthreads", "1", "--scheduler-file", str(self.scheduler_file),
            "--no-dashboard", "--host", "127.0.0.1"]))
        from distributed import Client

        with Client(scheduler_file=str(self.scheduler_file), timeout="10s", set_as_default=False) as client:
            client.wait_for_workers(n, timeout=timeout)

    def kill_scheduler(self) -> None:
        """SIGKILL the scheduler (no goodbye to its clients)."""
        self._kill(self.scheduler)

    def kill_workers(self) -> None:
        """SIGKILL every worker process and its nanny: the scheduler loses them all."""
        for p in self.workers:
            self._kill(p)

    @staticmethod
    def _kill(p: subprocess.Popen | None) -> None:
        """SIGKILL ``p``'s process group, all but ``multiprocessing``'s resource trackers: left alive, each sees its
        clients gone and unlinks the named semaphores they left in /dev/shm (killed, they stayed there)."""
        if p is None:
            return
        members = _group(p.pid)
        with contextlib.suppress(ProcessLookupError):
            if members is None:  # no /proc: the whole group
                os.killpg(p.pid, signal.SIGKILL)
            for pid in members or []:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        p.wait(timeout=30)

    def close(self) -> None:
        """Stop the workers, then the scheduler: SIGTERM first, so that their processes end their
        ``multiprocessing`` resources (each SIGKILLed nanny left its named semaphores in /dev/shm, 12 a test);
        SIGKILL what is still running after :data:`STOP_S` seconds."""
        for p in [*self.workers, self.scheduler]:
            if p is None or p.poll() is not None:
                continue
            try:
                os.killpg(p.pid, signal.SIGTERM)
                p.wait(timeout=STOP_S)
            except ProcessLookupError:
                pass
            except subprocess.TimeoutExpired:
                self._kill(p)


def _group(pgid: int) -> list[int] | None:
    """The processes of process group ``pgid`` other than resource trackers (None without /proc)."""
    if not os.path.isdir("/proc/self"):
        return None
    found = []
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", encoding="utf-8", errors="replace") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            with open(f"/proc/{name}/cmdline", "rb") as fh:
                command = fh.read()
        except OSError:
            continue
        if int(fields[2]) == pgid and b"resource_tracker" not in command:
            found.append(int(name))
    return found
