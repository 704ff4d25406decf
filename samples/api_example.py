"""The Python API as a typed script: what ``make test`` type-checks (mypy) against the package's hints.

Run it with ``python -m pyramid_cli.samples.api_example`` (or ``python samples/api_example.py``): it blurs,
reduces and expands an 8-bit picture, builds its pyramid and Laplacian bands and writes nothing.
"""

from __future__ import annotations

import warnings

import numpy as np

import pyramid_cli as pyr


def tour(codes: np.ndarray) -> dict[str, np.ndarray]:
    """Each API function once on 8-bit ``codes`` (H×W×C): results of the input's dtype, by name."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pyr.PyramidWarning)  # e.g. no GL here: the CPU runs it
        soft: np.ndarray = pyr.blur(codes, 2, border="symmetric")
        half: np.ndarray = pyr.reduce(codes, analysis="quadratic")
        double: np.ndarray = pyr.expand(half, synthesis="doosabin", dtype=np.float32)
        levels: list[np.ndarray] = list(pyr.pyramid(codes, levels=2))
        bands: pyr.Bands = pyr.laplacian(codes, 2)
        back: np.ndarray = pyr.collapse(bands, dtype=codes.dtype)
        mips: list[np.ndarray] = pyr.mipmap(codes, border="periodic")
    return {"blur": soft, "reduce": half, "expand": double, "level 2": levels[-1], "collapse": back,
            "mip 1x1": mips[-1]}


def main() -> None:
    codes = np.random.default_rng(0).integers(0, 256, (32, 24, 3)).astype(np.uint8)
    for name, result in tour(codes).items():
        print(f"{name}: {result.dtype} {result.shape}")
    work: pyr.Work = pyr.TextureLevels(levels=None, border="wrap")
    print(f"a job value for process_files: {work.label}")


if __name__ == "__main__":
    main()
