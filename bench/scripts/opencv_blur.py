"""The OpenCV peer of `pyramid blur --levels 5`: pyrDown⁵/pyrUp⁵ between a read and a write.

    python bench/scripts/opencv_blur.py MODE IN OUT [IN OUT …]    # prints the seconds the loop took

MODE "oiio-exr" reads and writes EXR with OpenImageIO (for OpenCV builds without the
OpenEXR codec, e.g. the opencv-python-headless 5.0 wheels); the filter stays OpenCV's.
"""

import os
import sys
import time

os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"
import cv2  # noqa: E402
import numpy as np  # noqa: E402

t0 = time.perf_counter()
mode, a = sys.argv[1], sys.argv[2:]
for src, dst in zip(a[0::2], a[1::2], strict=True):
    exr = src.endswith(".exr")
    if exr and mode == "oiio-exr":
        import OpenImageIO as oiio

        inp = oiio.ImageInput.open(src)
        spec = inp.spec()
        x = inp.read_image(0, 0, 0, spec.nchannels, "float")
        inp.close()
    else:
        x = cv2.imread(src, cv2.IMREAD_UNCHANGED)
    eight = x.dtype == np.uint8
    x = x.astype(np.float32) / 255 if eight else x.astype(np.float32)
    sizes = [x.shape[:2]]
    for _ in range(5):
        x = cv2.pyrDown(x)
        sizes.append(x.shape[:2])
    for k in range(5, 0, -1):
        h, w = sizes[k - 1]
        x = cv2.pyrUp(x, dstsize=(w, h))
    if eight:
        cv2.imwrite(dst, np.clip(np.rint(x * 255), 0, 255).astype(np.uint8), [cv2.IMWRITE_PNG_COMPRESSION, 6])
    elif mode == "oiio-exr":
        spec = oiio.ImageSpec(x.shape[1], x.shape[0], x.shape[2], "half")
        spec.attribute("compression", "piz" if "piz" in src else "zip")
        out = oiio.ImageOutput.create(dst)
        out.open(dst, spec)
        out.write_image(x.astype(np.float16))
        out.close()
    else:
        comp = cv2.IMWRITE_EXR_COMPRESSION_PIZ if "piz" in src else cv2.IMWRITE_EXR_COMPRESSION_ZIP
        cv2.imwrite(dst, x, [cv2.IMWRITE_EXR_TYPE, cv2.IMWRITE_EXR_TYPE_HALF, cv2.IMWRITE_EXR_COMPRESSION, comp])
print(time.perf_counter() - t0)
