"""The repository's folders, wherever a test module sits under ``tests/``."""

from pathlib import Path

#: The repository's root (the folder holding ``pyproject.toml``).
ROOT = Path(__file__).resolve().parents[2]
#: Data files the tests read (``tests/data``).
DATA = ROOT / "tests" / "data"
#: The shipped sample images.
SAMPLES = ROOT / "samples"
