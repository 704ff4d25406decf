"""CPU time, wall time and peak resident memory of a command: python bench/scripts/peak_rss.py CMD [ARG …].

Prints ``CPU SECONDS MIB``: the child's CPU seconds (user and system), the seconds from fork to its exit, and its
peak RSS in MiB (the last field, which callers that want only the memory take; the last two, callers that want the
time and the memory). The command is forked from this small process
(not from the benchmark, whose high-water mark a forked child would inherit across exec) and its own
rusage is printed; its standard output is discarded, its standard error passes through.
"""
import os
import sys
import time

t0 = time.perf_counter()
pid = os.fork()
if pid == 0:
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        os.execvp(sys.argv[1], sys.argv[1:])
    finally:
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
seconds = time.perf_counter() - t0
code = os.waitstatus_to_exitcode(status)
if code:
    sys.exit(code)
print(usage.ru_utime + usage.ru_stime, seconds, usage.ru_maxrss / 1024)
