"""A contact sheet: images side by side on a grey background (``levels --sheet``, the demo's figures)."""

from __future__ import annotations

import numpy as np


def contact_sheet(panels: list[np.ndarray], gap: int = 8) -> np.ndarray:
    """Panels side by side on a mid-grey background, top-aligned; RGB float32 (grey panels are repeated)."""
    h = max(p.shape[0] for p in panels)
    w = sum(p.shape[1] for p in panels) + gap * (len(panels) - 1)
    out = np.full((h, w, 3), 0.2, dtype=np.float32)
    x = 0
    for p in panels:
        rgb = p if p.ndim == 3 else p[:, :, None]
        if rgb.shape[2] < 3:
            rgb = np.repeat(rgb[:, :, :1], 3, axis=2)
        out[:p.shape[0], x:x + p.shape[1]] = rgb[..., :3]
        x += p.shape[1] + gap
    return out


__all__ = ["contact_sheet"]
