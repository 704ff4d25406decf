"""Peak resident memory of a command, in MB: python bench/scripts/peak_rss.py CMD [ARG …].

The command is forked from this small process (not from the benchmark, whose high-water mark a
forked child would inherit across exec) and its own rusage is printed.
"""
import os
import sys

pid = os.fork()
if pid == 0:
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        os.execvp(sys.argv[1], sys.argv[1:])
    finally:
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
code = os.waitstatus_to_exitcode(status)
if code:
    sys.exit(code)
print(usage.ru_maxrss / 1024)
