"""One process, one Session, the CLI's own read / run / write functions: what a batch loop in Python does.

    python bench/scripts/pyramid_batch.py IN OUT [IN OUT …]    # prints: loop seconds, import + set-up seconds
"""
import sys
import time

t0 = time.perf_counter()
from pyramid_cli import imageio as io  # noqa: E402
from pyramid_cli.exec.session import Session  # noqa: E402
from pyramid_cli.jobs.work import Blur  # noqa: E402

session = Session("gl")
work = Blur(levels=5)
t1 = time.perf_counter()
a = sys.argv[1:]
for src, dst in zip(a[0::2], a[1::2], strict=True):
    image = io.read_image(src)
    (image.pixels,) = session.run(work, [image.pixels])
    io.write_image(dst, image, inputs=(src,))
session.close()
print(time.perf_counter() - t1, t1 - t0)
