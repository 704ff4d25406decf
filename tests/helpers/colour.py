"""A small OpenColorIO v2 studio config, and OpenImageIO's own colour conversion as the oracle of the tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio

# ACEScg-like reference (plate_lin), a log space of it with a file rule, an sRGB texture space with
# Rec.709 primaries, and a data space: names no built-in config has.
AP1_TO_709 = "[1.7049, -0.6217, -0.0833, 0, -0.1301, 1.1407, -0.0106, 0, -0.0240, -0.1290, 1.1530, 0, 0, 0, 0, 1]"
STUDIO = f"""ocio_profile_version: 2

roles:
  default: plate_lin
  scene_linear: plate_lin
  data: matte
  color_picking: tex_srgb

file_rules:
  - !<Rule> {{name: logplates, colorspace: plate_log, pattern: "*_log*", extension: "*"}}
  - !<Rule> {{name: Default, colorspace: default}}

displays:
  monitor:
    - !<View> {{name: raw, colorspace: matte}}

colorspaces:
  - !<ColorSpace>
    name: plate_lin
    aliases: [studio_linear]
    encoding: scene-linear
  - !<ColorSpace>
    name: plate_log
    encoding: log
    from_scene_reference: !<LogAffineTransform>
      {{base: 2, logSideSlope: 0.05, logSideOffset: 0.5, linSideOffset: 0.0078125}}
  - !<ColorSpace>
    name: tex_srgb
    aliases: [studio_texture]
    encoding: sdr-video
    from_scene_reference: !<GroupTransform>
      children:
        - !<MatrixTransform> {{matrix: {AP1_TO_709}}}
        - !<ExponentWithLinearTransform> {{gamma: 2.4, offset: 0.055, direction: inverse}}
  - !<ColorSpace>
    name: matte
    encoding: data
    isdata: true
"""


def studio_config(folder) -> Path:
    """Write the studio config into ``folder``; its path."""
    path = Path(folder) / "studio.ocio"
    path.write_text(STUDIO)
    return path


def ocio(pixels, src: str, dst: str, config: str = "") -> np.ndarray:
    """``pixels`` (H×W×C float) converted by OpenImageIO's ``ImageBufAlgo.colorconvert`` (no unpremultiply)."""
    buf = oiio.ImageBuf(np.ascontiguousarray(pixels, dtype=np.float32))
    out = oiio.ImageBufAlgo.colorconvert(buf, src, dst, False, "", "", config)
    assert not out.has_error, out.geterror()
    return np.asarray(out.get_pixels(oiio.FLOAT), dtype=np.float32)
