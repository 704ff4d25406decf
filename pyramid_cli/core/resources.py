"""Files shipped inside the package (the cost models, the shader templates), read through their package's loader.

``pkgutil.get_data`` asks the loader that imported the package, so it reads from a wheel, a source tree or a zip
alike. ``importlib.resources`` does too, but importing it brings ``tempfile``, ``shutil``, ``zipfile`` and their
own imports, about 5 ms of every run's start (``python -X importtime``), for a read of a few kilobytes.
"""

from __future__ import annotations

import json
import pkgutil
from typing import Any


def text(package: str, name: str) -> str:
    """The UTF-8 text of the file ``name`` beside the modules of ``package`` (FileNotFoundError when absent)."""
    data = pkgutil.get_data(package, name)
    if data is None:  # a loader that cannot read data files
        raise FileNotFoundError(f"{name} is not readable in {package}")
    return data.decode("utf-8")


def json_file(package: str, name: str) -> Any:
    """The JSON file ``name`` beside the modules of ``package``, parsed."""
    return json.loads(text(package, name))


__all__ = ["json_file", "text"]
