"""Wall time and peak resident memory of a command: python bench/scripts/peak_rss.py CMD [ARG …].

Prints ``SECONDS MIB``: the seconds from fork to the child's exit and its peak RSS in MiB (the last
field, which callers that want only the memory take). The command is forked from this small process
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
print(seconds, usage.ru_maxrss / 1024)
