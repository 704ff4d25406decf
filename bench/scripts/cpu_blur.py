"""The CPU executor's warm 5-level blur against OpenCV's pyrDown⁵/pyrUp⁵, interleaved in one process.

    python bench/scripts/cpu_blur.py ROWS COLS REPS    # prints JSON: each one's median and runs

RGBA float32 (``bench/run.py``'s gradient plus noise); the executor runs the planner's ``fused`` blur
plan with its kernels loaded before timing, OpenCV its own 5-tap filters (``run.peer_blurs``). Run it
with PYTHONPATH naming a checkout to time that checkout's executor.
"""

import json
import sys
from pathlib import Path

import pyramid_cli  # first, so the checkout on PYTHONPATH wins over the one bench/run.py puts on sys.path
from pyramid_cli.exec import cpu
from pyramid_cli.workflows.pyramids import blur_plan, level_sizes

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import cv2  # noqa: E402
from run import gradient_noise, interleaved, peer_blurs  # noqa: E402

rows, cols, reps = (int(a) for a in sys.argv[1:4])
img = gradient_noise(rows, cols, 4)
plan = blur_plan((rows, cols), 5, strategy="fused")
ex = cpu.CPUExecutor()
ex.prepare(plan)
cv_blur = peer_blurs(cv2, level_sizes((rows, cols), 5))[0]
res = interleaved({"pyramid": lambda: ex.run(plan, img), "opencv": lambda: cv_blur(img)}, reps)
print(json.dumps({"tree": str(Path(pyramid_cli.__file__).resolve().parent.parent), "executor": ex.info(),
                  "opencv_threads": cv2.getNumThreads(), "results": res}, default=str))
