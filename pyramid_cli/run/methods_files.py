"""Files in, files out for the pyramid methods: ``pyramid fill`` and ``pyramid blend``.

Read → weights and masks → one plan on the session's executor → write, with the CLI's read and
write options (:class:`~pyramid_cli.run.settings.ReadOptions`, ``WriteOptions``) and its reporter.
"""

from __future__ import annotations

import contextlib
import dataclasses

import numpy as np

from pyramid_cli import imageio as io
from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import InputError, UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Blend, Fill
from pyramid_cli.run.codec_budget import holds_codec_limits
from pyramid_cli.run.inputs import read_input
from pyramid_cli.run.report import NAN_HINT, Reporter, announce_compiles
from pyramid_cli.run.settings import ReadOptions, WriteOptions
from pyramid_cli.run.stream_many import blend_streamed, fill_streamed, mask_layout
from pyramid_cli.workflows.methods import fill_inputs, fill_output, mask_channels, mask_weights


def _read_mask(path: str, shape: tuple[int, ...], ro: ReadOptions, reporter: Reporter) -> np.ndarray:
    """A mask or weight image as stored values (no sRGB decoding, no alpha rules): H×W or H×W×C.

    One channel is taken as it is, as many channels as ``shape`` give one weight per channel; any other
    count takes the mask's alpha channel (an RGBA matte for an RGB image; -v says so), and without one is
    refused naming both counts. NaN/Inf and values outside [0, 1] are
    :func:`~pyramid_cli.workflows.methods.mask_weights`'.
    """
    m = io.read_image(path, colorspace="linear", alpha="none", nan=ro.nan, colorconfig=ro.colorconfig)
    px = m.pixels
    alpha = mask_layout(path, m.spec, px.shape, shape, reporter.warn)
    if alpha is None:
        return px
    return px[:, :, alpha]


@holds_codec_limits
def fill_file(input_path: str, output_path: str, session: Session, *, mask: str | None = None,
              holes: str | None = None, levels: int | None = None, analysis: str = catalogue.FILL_ANALYSIS,
              synthesis: str = catalogue.FILL_SYNTHESIS, weight_scale: int | tuple[int, int] = catalogue.FILL_SCALE,
              sweeps: int | tuple[int, int] = catalogue.FILL_SWEEPS, keep_alpha: bool = False, border: str = "clamp",
              allow_mixed_lattice: bool = False, read: ReadOptions | None = None, write: WriteOptions | None = None,
              reporter: Reporter | None = None, memory: int | None = None,
              limits: contextlib.ExitStack | None = None) -> dict:
    """Pull-push fill of one image file (:func:`pyramid_cli.api.fill`); returns what ``--json`` prints.

    ``keep_alpha`` writes the input's alpha beside the filled colours, stored unassociated (as they
    are: what a PNG's straight alpha means; in EXR, for readers that take its colour as unassociated).
    A pull of ``levels`` that stops at 16 rows or more streams band by band
    (:func:`pyramid_cli.run.stream_many.fill_streamed`) when the whole run would not fit ``memory`` bytes
    (default: :func:`pyramid_cli.run.budget.default_budget`) or is slower than bands; the bytes are the whole
    run's. A pull down to 1×1 (the default) needs every row before the first: it runs whole."""
    ro, wo, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    holes = holes or ("mask" if mask else "alpha")
    if holes == "mask" and not mask:
        raise UsageError("--holes mask needs --mask IMAGE")
    if mask and holes != "mask":
        raise UsageError(f"--mask gives the weights; it cannot be combined with --holes {holes}")
    if keep_alpha and holes != "alpha":
        raise UsageError(f"--keep-alpha keeps the alpha the holes come from; with --holes {holes} every channel "
                         "is filled")
    if holes == "nan" and ro.nan != "keep":
        raise UsageError(f"--holes nan fills the NaN/Inf pixels; --nan {ro.nan} would remove them first")
    io.check_write_options(output_path, wo.pixel_type, wo.compression, wo.tocolorspace, ro.colorconfig)

    def work_for(premultiplied: bool) -> Fill:  # the one Fill of both runs, whole and streamed
        return Fill(levels=levels, analysis=analysis, synthesis=synthesis, premultiplied=premultiplied, border=border,
                    weight_scale=weight_scale, sweeps=sweeps, allow_mixed_lattice=allow_mixed_lattice)

    def done(w: int, h: int, counts: dict, how: str = "") -> dict:
        info = {"output": output_path, "width": w, "height": h, "holes": holes, **counts,
                "levels": _levels(work_for(True), (h, w)), "analysis": analysis, "synthesis": synthesis,
                "weight_scale": weight_scale, "sweeps": sweeps, "border": border, "executor": session.ran}
        reporter.result(f"wrote {output_path} ({w}×{h}, {info['empty']} empty and {info['partial']} partial "
                        f"pixel(s) filled, {session.ran}{how})")
        return info

    streamed = fill_streamed(input_path, output_path, session, work_for, mask=mask, holes=holes, levels=levels,
                             keep_alpha=keep_alpha, memory=memory, read=ro, write=wo, reporter=reporter,
                             limits=limits)
    if streamed is not None:
        (h, w), counts, band = streamed
        return done(w, h, counts, f", streamed in bands of {band} rows")
    # a half file stays half until fill_inputs copies it to float32 (one conversion, not two)
    image = io.read_image(input_path, colorspace=ro.colorspace, alpha=ro.alpha, nan=ro.nan, keep_half=True,
                          colorconfig=ro.colorconfig)
    px = image.pixels
    alpha = image.spec.alpha_channel if image.premultiplied else None
    if holes == "alpha" and alpha is None:
        raise UsageError(f"{input_path}: no alpha channel to take the holes from; give --mask IMAGE or --holes nan")
    weights = (mask_weights(_read_mask(mask, px.shape, ro, reporter), px, mask, reporter.warn, nan_hint=NAN_HINT)
               if mask else None)
    # the weights are checked, and what they hold said, above
    colour, weight, premultiplied = fill_inputs(px, holes, weights, alpha, where=input_path, warn=lambda _: None)
    work = work_for(premultiplied)
    for message in work.warnings(px.shape[:2]):
        reporter.warn(message)
    announce_compiles(session, work, [colour, weight], reporter)
    (filled,) = session.run(work, [colour, weight])
    out = fill_output(filled, px, holes, alpha, keep_alpha)
    spec = dataclasses.replace(image.spec, alpha_mode="none") if keep_alpha else image.spec  # colours as they are
    io.write_image(output_path, io.Image(np.ascontiguousarray(out, dtype=np.float32), spec),
                   **wo.for_inputs([input_path] + ([mask] if mask else [])))
    h, w = out.shape[:2]
    w0 = weight[..., 0]
    reporter.detail(f"{io.describe_rules(image.spec)}; executor {session.ran}")
    return done(w, h, {"known": int(np.sum(w0 >= 1)), "partial": int(np.sum((w0 > 0) & (w0 < 1))),
                       "empty": int(np.sum(w0 <= 0))})


def fill_texture(image: io.Image, session: Session, border: str = "clamp", where: str = "") -> io.Image:
    """``pyramid mipmap --fill``: the texture filled by pull-push where its alpha is below 1 (the empty
    texels around UV islands), opaque, before its MIP levels are made. Texels of alpha 1 are unchanged.
    ``border`` is the MIP chain's (a tileable texture's holes fill from across its edges)."""
    px = np.asarray(image.pixels, dtype=np.float32)
    if not image.premultiplied:
        raise UsageError(f"{where}: --fill takes the holes from the alpha channel, and this texture has none")
    alpha = image.spec.alpha_channel
    colour, weight, premultiplied = fill_inputs(px, "alpha", None, alpha, where=where)
    (filled,) = session.run(Fill(premultiplied=premultiplied, border=border), [colour, weight])
    return io.Image(np.ascontiguousarray(fill_output(filled, px, "alpha", alpha), dtype=np.float32), image.spec)


def _levels(work, size) -> int:
    from pyramid_cli.core.geometry import mip_levels

    return mip_levels(tuple(size)) if work.levels is None else work.levels


@holds_codec_limits
def blend_files(a_path: str, b_path: str, mask_path: str, output_path: str, session: Session, *,
                levels: int | None = None, analysis: str = catalogue.DEFAULT_ANALYSIS,
                synthesis: str = catalogue.DEFAULT_SYNTHESIS, border: str = "clamp", allow_mixed_lattice: bool = False,
                read: ReadOptions | None = None, write: WriteOptions | None = None,
                reporter: Reporter | None = None, memory: int | None = None,
                limits: contextlib.ExitStack | None = None) -> dict:
    """Multiresolution blend of two image files along a mask file (:func:`pyramid_cli.api.blend`).

    Streams band by band (:func:`pyramid_cli.run.stream_many.blend_streamed`) when the whole run would not fit
    ``memory`` bytes (default: :func:`pyramid_cli.run.budget.default_budget`) or is slower than bands (from a
    megapixel on the CPU executor: :func:`pyramid_cli.run.stream.speed_band`); the bytes are the whole run's."""
    ro, wo, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    io.check_write_options(output_path, wo.pixel_type, wo.compression, wo.tocolorspace, ro.colorconfig)
    work = Blend(levels=levels, analysis=analysis, synthesis=synthesis, border=border,
                 allow_mixed_lattice=allow_mixed_lattice)
    streamed = blend_streamed(a_path, b_path, mask_path, output_path, work, session, memory=memory, read=ro,
                              write=wo, reporter=reporter, limits=limits)
    if streamed is not None:
        return streamed
    a = read_input(a_path, ro, reporter)
    b = read_input(b_path, ro, reporter)
    if a.pixels.shape != b.pixels.shape:
        raise InputError(f"{b_path}: {b.pixels.shape[1]}×{b.pixels.shape[0]} with {b.pixels.shape[2]} channel(s); "
                         f"{a_path} is {a.pixels.shape[1]}×{a.pixels.shape[0]} with {a.pixels.shape[2]}")
    mask = mask_channels(_read_mask(mask_path, a.pixels.shape, ro, reporter), a.pixels, where=mask_path,
                         warn=reporter.warn, nan_hint=NAN_HINT)
    # B in A's linear space (both linear: one matrix), so that the blend mixes like with like
    b_pixels = io.pixels_in(b, a.spec.linear_space) if b.spec.linear_space != a.spec.linear_space else b.pixels
    images = [a.pixels, b_pixels, mask]
    work.check(tuple(im.shape[:2] for im in images), where=a_path)
    for message in work.warnings(a.pixels.shape[:2]):
        reporter.warn(message)
    announce_compiles(session, work, images, reporter)
    (out,) = session.run(work, images)
    io.write_image(output_path, io.Image(out, a.spec), **wo.for_inputs([a_path, b_path, mask_path]))
    h, w = out.shape[:2]
    reporter.detail(f"{io.describe_rules(a.spec)}; executor {session.ran}")
    reporter.result(f"wrote {output_path} ({w}×{h}, {work.count((h, w))} level(s), {session.ran})")
    return {"output": output_path, "width": w, "height": h, "levels": work.count((h, w)), "analysis": analysis,
            "synthesis": synthesis, "border": border, "executor": session.ran}


__all__ = ["fill_file", "blend_files", "fill_texture"]
