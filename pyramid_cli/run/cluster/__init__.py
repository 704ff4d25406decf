"""A batch on a Dask distributed cluster (``--cluster ADDRESS``; optional extra ``[cluster]``).

The client plans the job list (sequences, shards) as in one process, cuts it into
contiguous chunks and submits one task per chunk. Each worker holds one executor (a
:class:`~pyramid_cli.exec.session.Session`) for its whole life through a worker plugin
(:class:`SessionPlugin`), opened at its first task in the thread that runs tasks and
closed when the worker stops. Workers read inputs and write outputs on the shared
storage themselves: only job lists, reports and messages travel through the scheduler.

What the run says is one process's: chunks' lines are printed in job order (a chunk
that finishes early waits for those before it), and the report counts what happened on
disk however chunks failed or ran again.

- A worker that dies mid-chunk is the scheduler's to retry (it reschedules the chunk on
  another worker; ``retries=`` covers tasks that raise). Outputs are written atomically
  (hidden temporary file, then rename), and a chunk that runs again first removes the
  temporary files its dead predecessor left and reports the outputs written since the
  batch started as written (the line a local run prints, from the file's header) without
  writing them again: neither half-written nor duplicate files, nor missing lines.
- Without ``--keep-going`` the first failed chunk sets a stop (a ``distributed.Variable``
  holding its index): chunks after it that have not started do nothing, as a local run
  never starts the jobs after a failure; chunks already running finish and are counted.
- A chunk the cluster cannot run, the scheduler lost, or no worker connected for
  ``timeout`` seconds fail the frames not done with one :class:`ClusterError` naming them;
  outputs already on disk count as written.
- Dask's own log lines and warnings never reach the terminal: they are captured for the
  run, and ``-v`` says what happened in this tool's words (a worker lost, a chunk
  rescheduled).

Addresses are whatever ``distributed.Client`` accepts (``tcp://``, ``HOST:PORT``,
``tls://``, ``ws://``, ``wss://``, ``inproc://``, ``ucx://``), a scheduler file, or
``local:N``; anything that cannot be used is refused in one line (exit 2), a refused TCP
connection at once (a plain socket connect first, before Dask is imported).
"""

from pyramid_cli.run.cluster.connection import INSTALL_HINT, TIMEOUT, Target, connect, require, resolve
from pyramid_cli.run.cluster.gather import MAX_CHUNK, ClusterError, chunks, default_chunk, describe_jobs, run_cluster
from pyramid_cli.run.cluster.logs import captured_output
from pyramid_cli.run.cluster.worker import (
    CRASH_VARIABLE,
    PLUGIN_NAME,
    SLOW_VARIABLE,
    ChunkResult,
    SessionPlugin,
    SessionSpec,
    run_chunk,
)

__all__ = ["SessionSpec", "SessionPlugin", "ClusterError", "ChunkResult", "Target", "run_cluster", "run_chunk",
           "connect", "resolve", "captured_output", "describe_jobs", "chunks", "default_chunk", "require",
           "PLUGIN_NAME", "CRASH_VARIABLE", "SLOW_VARIABLE", "TIMEOUT", "MAX_CHUNK", "INSTALL_HINT"]
