"""Reaching a Dask cluster (``--cluster ADDRESS``): the address checked without Dask where it can be (a refused
TCP connection fails at once), a scheduler file read, ``local:N`` started, the scheduler asked who it is, and a
``distributed.Client`` opened; anything that cannot be used is refused in one line (exit 2).
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib.util
import json
import logging
import os
import re
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pyramid_cli.core.errors import UsageError

if TYPE_CHECKING:  # distributed is an optional extra, imported when a cluster is used
    from distributed import Client

INSTALL_HINT = "pip install 'bilinear-pyramid[cluster]'"
#: ``--cluster-timeout``'s default, in seconds: connecting, a scheduler file to appear, no worker connected.
TIMEOUT = 30.0
DEFAULT_PORT = 8786  # Dask's, for an address without one


def require() -> None:
    """Raise a :class:`UsageError` (exit 2) naming the extra when Dask distributed is not installed."""
    try:
        found = importlib.util.find_spec("distributed") is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise UsageError(f"--cluster needs Dask distributed: {INSTALL_HINT}")


def one_line(e: BaseException) -> str:
    """An exception in one line: its type and the first line of its message."""
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__



@dataclass(frozen=True)
class Target:
    """Where ``--cluster`` points, checked as far as it can be without Dask: ``local:N`` or a scheduler address.

    ``label`` names it in messages (the scheduler file it came from, if any).
    """

    address: str
    label: str
    local: int = 0
    scheme: str = "tcp"


def _host_port(location: str, label: str) -> tuple[str, int]:
    m = re.fullmatch(r"\[([0-9A-Fa-f:.%\w]+)\](?::(\d+))?|([^\s:/\[\]@]+)(?::(\d+))?", location)
    if not m:
        raise UsageError(f"--cluster {label}: expected HOST:PORT after the scheme (e.g. tcp://scheduler:8786)")
    host = m.group(1) or m.group(3)
    port = int(m.group(2) or m.group(4) or DEFAULT_PORT)
    if not 0 < port < 65536:
        raise UsageError(f"--cluster {label}: port {port} is not a TCP port (1–65535)")
    return host, port


def _probe(host: str, port: int, label: str, timeout: float) -> None:
    """A plain TCP connect, so a refused or unknown address is reported at once (Dask retries until its timeout)."""
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except ConnectionRefusedError:
        raise UsageError(f"--cluster {label}: connection refused: no Dask scheduler listens on {host}:{port}") from None
    except socket.gaierror as e:
        raise UsageError(f"--cluster {label}: unknown host {host} ({e.strerror})") from None
    except TimeoutError:
        raise UsageError(f"--cluster {label}: no answer from {host}:{port} in {timeout:g} s "
                         "(--cluster-timeout)") from None
    except OSError as e:
        raise UsageError(f"--cluster {label}: cannot connect to {host}:{port} ({e.strerror or e})") from None


def _scheduler_file(path: str, timeout: float) -> str:
    """The address in a ``dask scheduler --scheduler-file`` file, waiting up to ``timeout`` for it as Dask does."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            with open(path, encoding="utf-8") as f:
                address = json.load(f).get("address")
            if isinstance(address, str) and address:
                return address
            problem = "no scheduler address in the file"
        except FileNotFoundError:
            problem = "no such scheduler file"
        except (OSError, ValueError, AttributeError) as e:  # half written, or not a scheduler file
            problem = f"not a Dask scheduler file ({e.strerror if isinstance(e, OSError) else 'not JSON'})"
        if time.monotonic() >= deadline:
            raise UsageError(f"--cluster {path}: {problem} after {timeout:g} s (--cluster-timeout; "
                             "dask scheduler --scheduler-file writes the file)")
        time.sleep(0.1)


def resolve(cluster: str | os.PathLike, timeout: float = TIMEOUT) -> Target:
    """Check ``--cluster``'s value without importing Dask: a refused or malformed TCP address fails here, fast.

    Raises
    ------
    UsageError
        ``local:N`` with N < 1, a scheduler file that does not appear in ``timeout``, an address
        that is not one, a host that does not resolve, a refused connection, no answer in ``timeout``.
    """
    text = os.fspath(cluster).strip()
    if text.startswith("local:"):
        n = int(text[6:]) if text[6:].isdigit() else 0
        if n < 1:
            raise UsageError(f"--cluster {text!r}: expected local:N with N ≥ 1 worker processes")
        return Target(text, text, local=n, scheme="local")
    label = text
    if "://" not in text and (text.lower().endswith(".json") or os.sep in text or os.path.isfile(text)):
        text = _scheduler_file(text, timeout)
        label = f"{text} (from {label})"
    scheme, sep, location = text.partition("://")
    if not sep:
        scheme, location = "tcp", text
    scheme = scheme.lower()
    if scheme in ("tcp", "tls", "ws", "wss"):
        host, port = _host_port(location, label)
        _probe(host, port, label, timeout)
        text = f"{scheme}://{f'[{host}]' if ':' in host else host}:{port}"
    return Target(text, label, scheme=scheme)


def _security(target: Target):
    """The Dask configuration's TLS settings (``distributed.comm.tls.*``) for tls:// and wss://, or a refusal."""
    from distributed import Security

    try:
        security = Security()
        context = security.get_connection_args("client").get("ssl_context")
    except Exception as e:  # noqa: BLE001 - a missing or bad certificate file, whatever the library raises
        raise UsageError(f"--cluster {target.label}: the Dask TLS configuration cannot be used "
                         f"({one_line(e)})") from None
    if context is None:
        raise UsageError(f"--cluster {target.label}: {target.scheme}:// needs certificates: set "
                         "distributed.comm.tls.ca-file, distributed.comm.tls.client.cert and .client.key in the Dask "
                         "configuration (~/.config/dask/distributed.yaml or DASK_DISTRIBUTED__COMM__TLS__… variables)")
    return security


def _check_scheme(target: Target) -> None:
    """Refuse in one line what Dask cannot connect to from here (unknown schemes, UCX missing, inproc elsewhere)."""
    from distributed.comm import registry

    if target.scheme == "inproc":
        from distributed.comm.inproc import global_manager

        try:
            listener = global_manager.get_listener_for(target.address.partition("://")[2])
        except ValueError:  # another process's, or not an inproc address at all
            listener = None
        if listener is None:
            raise UsageError(f"--cluster {target.label}: no scheduler in this process listens there (an inproc:// "
                             "address reaches a scheduler in the same Python process)")
        return
    try:
        registry.get_backend(target.scheme).get_connector()
    except ValueError:
        raise UsageError(f"--cluster {target.label}: unknown address scheme {target.scheme}:// (Dask's: "
                         f"{', '.join(s + '://' for s in sorted(registry.backends))}; or HOST:PORT, local:N, "
                         "a scheduler file)") from None
    except Exception as e:  # noqa: BLE001 - a backend whose library is missing (ucx) fails in its own way
        extra = " (install distributed-ucxx)" if target.scheme == "ucx" else ""
        raise UsageError(f"--cluster {target.label}: {target.scheme}:// cannot be used on this machine{extra}: "
                         f"{one_line(e)}") from None


def _identify(target: Target, security, timeout: float) -> None:
    """Ask the address who it is, within ``timeout``: a listener that is not a Dask scheduler, or one that
    never answers, makes ``distributed.Client`` wait forever."""
    from distributed.comm import connect as dask_connect

    args = security.get_connection_args("client") if security is not None else {}
    answer: list = []

    async def ask():
        comm = await dask_connect(target.address, timeout=timeout, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    def run() -> None:  # a thread of its own: the caller may be inside an event loop (Jupyter)
        try:
            answer.append(asyncio.run(asyncio.wait_for(ask(), timeout)))
        except BaseException as e:  # noqa: BLE001 - reported below in one line
            answer.append(e)

    thread = threading.Thread(target=run, name="pyramid-cluster-identify", daemon=True)
    thread.start()
    thread.join(timeout + 1)
    reply = answer[0] if answer else TimeoutError()
    if isinstance(reply, TimeoutError):
        raise UsageError(f"--cluster {target.label}: no Dask scheduler answered in {timeout:g} s (--cluster-timeout)")
    if isinstance(reply, BaseException):
        raise UsageError(f"--cluster {target.label}: cannot talk to a Dask scheduler there ({one_line(reply)})")
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        kind = reply.get("type") if isinstance(reply, dict) else type(reply).__name__
        raise UsageError(f"--cluster {target.label}: answered, but is not a Dask scheduler ({kind})")


@contextlib.contextmanager
def connect(cluster, timeout: float = TIMEOUT) -> Iterator[tuple[Client, str]]:
    """``(distributed.Client, label)`` for ``cluster``: a Client (used as is), ``local:N``, a scheduler file or address.

    ``local:N`` starts ``LocalCluster(n_workers=N, processes=True, threads_per_worker=1)``
    on 127.0.0.1 without a dashboard, for the duration of the block. A client this opens
    is closed at the end of the block. Anything that cannot be connected to raises a one-line
    :class:`UsageError` within about ``timeout`` seconds.
    """
    require()
    from distributed import Client, LocalCluster

    if isinstance(cluster, Client):
        yield cluster, str(cluster.scheduler.address)
        return
    target = cluster if isinstance(cluster, Target) else resolve(cluster, timeout)
    if target.local:
        with LocalCluster(n_workers=target.local, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None, silence_logs=logging.CRITICAL) as local, \
                Client(local, set_as_default=False) as client:
            yield client, target.label
        return
    _check_scheme(target)
    security = _security(target) if target.scheme in ("tls", "wss") else None
    if target.scheme != "inproc":
        _identify(target, security, timeout)
    try:
        client = Client(target.address, timeout=timeout, security=security, set_as_default=False)
    except Exception as e:  # noqa: BLE001 - whatever Dask raises, one line with the address
        raise UsageError(f"--cluster {target.label}: cannot connect ({one_line(e)})") from None
    try:
        yield client, target.label
    finally:
        with contextlib.suppress(Exception):
            client.close(timeout=min(timeout, 10))


__all__ = ["INSTALL_HINT", "TIMEOUT", "DEFAULT_PORT", "Target", "connect", "one_line", "require", "resolve"]
