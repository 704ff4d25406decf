"""cProfile of a module run as ``python -m MODULE``, in every Python thread it starts, merged into one stats file.

    python bench/scripts/profile_threads.py OUT.prof MODULE [ARG …]

``python -m cProfile`` sees the main thread only, where a pipeline that decodes and encodes in other
threads shows as lock waits. Here each thread started through ``threading`` (the CLI's I/O pools) gets a
profiler of its own on its first event, and their stats are merged with the main thread's: ``tottime``
then sums over the threads (decode, compute and encode each show their own time), and the main thread's
waits on them stay visible as ``acquire``. Native threads (numba's workers, OpenImageIO's) are not Python
threads: their time shows in the Python call that waits for them.
"""

import atexit
import cProfile
import pstats
import runpy
import sys
import threading

out, module = sys.argv[1], sys.argv[2]
profiles: list[cProfile.Profile] = []


def _start(frame, event, arg):  # a new thread's first profile event: give the thread its own profiler
    sys.setprofile(None)
    p = cProfile.Profile()
    profiles.append(p)
    p.enable()


def dump() -> None:
    """Merge and write the stats, once: from atexit, since ``pyramid``'s console script ends the process right
    after its atexit handlers (``core.signals.end``), or after a run that raised SystemExit as usual."""
    if not profiles or profiles[0] is not main:
        main.disable()
        threading.setprofile(None)
        profiles.insert(0, main)
        stats = pstats.Stats(main)
        for p in profiles[1:]:
            stats.add(p)
        stats.dump_stats(out)


threading.setprofile(_start)
main = cProfile.Profile()
atexit.register(dump)
sys.argv = [module, *sys.argv[3:]]
code = 0
main.enable()
try:
    runpy.run_module(module, run_name="__main__", alter_sys=True)
except SystemExit as e:
    code = e.code
finally:
    dump()
sys.exit(code)
