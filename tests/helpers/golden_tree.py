"""The out/ and golden/ folders the ``pyramid diff`` folder tests compare (tests/diff/conftest.py's ``tree``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from helpers.images import write


def img(seed: int, h: int = 8, w: int = 8, c: int = 4) -> np.ndarray:
    return np.random.default_rng(seed).random((h, w, c)).astype(np.float32)



def make_tree(tmp_path: Path) -> tuple[Path, Path]:
    """out/ and golden/: a passing pair, a failing pair, a missing golden, an extra golden,
    a pair passing through an alternative reference, a warning-free match in a subfolder."""
    out, gold = tmp_path / "out", tmp_path / "golden"
    write(out / "pass.exr", img(1))
    write(gold / "pass.exr", img(1))
    bad = img(2)
    write(out / "fail.exr", bad + 0.25)
    write(gold / "fail.exr", bad)
    write(out / "new.exr", img(3))                  # no golden: missing
    write(gold / "gone.exr", img(4))                # no output: extra
    write(out / "sub" / "alt.exr", img(5) + 0.5)
    write(gold / "sub" / "alt.exr", img(5))         # fails...
    write(gold / "sub" / "alt-gpu.exr", img(5) + 0.5)  # ...but this accepted alternative matches
    (gold / "notes.txt").write_text("not an image: never compared, never touched\n")
    return out, gold

