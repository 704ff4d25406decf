"""MIP-mapped files read back level by level, and two of them compared (the pixels and each level's header)."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio


def levels(path):
    """Every MIP level of ``path``: (pixels as stored, the spec's serialisation)."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    out = []
    try:
        sub, lev = 0, 0
        while True:
            if inp.supports("mipmap") or lev == 0:
                if not inp.seek_subimage(sub, lev):
                    break
            spec = inp.spec()
            text = "\n".join(ln for ln in spec.serialize().splitlines() if "DateTime" not in ln)  # the clock's
            out.append((inp.read_image(sub, lev, 0, spec.nchannels, spec.format), text))
            if inp.seek_subimage(sub, lev + 1):
                lev += 1
            elif inp.seek_subimage(sub + 1, 0):
                sub, lev = sub + 1, 0
            else:
                break
    finally:
        inp.close()
    return out


def assert_same_file(a, b):
    la, lb = levels(a), levels(b)
    assert len(la) == len(lb) > 1
    for (pa, sa), (pb, sb) in zip(la, lb, strict=True):
        assert pa.dtype == pb.dtype and np.array_equal(pa, pb)
        assert sa == sb
    attrs = {k: oiio.ImageInput.open(str(p)).spec().get_string_attribute(k) for p in (a,)
             for k in ("oiio:AverageColor", "oiio:SHA-1", "wrapmodes")}
    assert all(attrs.values()), attrs
