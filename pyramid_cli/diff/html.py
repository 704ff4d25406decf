"""Self-contained HTML report for ``pyramid diff --html DIR``.

``DIR/index.html`` plus one folder of PNGs (``DIR/img``), no network: per
pair, failures first, the statistics, A and B (click or press a key on the
picture to flip between them; ``index.html#B`` opens on B), the colour
difference and the alpha difference, each amplified so that its largest
error is full white (and sRGB-encoded, so small errors show).
Pictures are tone-mapped for display: stored integer code values are shown as
they are (they are display-encoded already); float and half values and
``--linear`` comparisons are clamped to 0-1 and sRGB-encoded.
"""

from __future__ import annotations

import html
import os
from collections.abc import Sequence

import numpy as np

from pyramid_cli.core.errors import OutputError, PyramidError
from pyramid_cli.diff.goldens import REPORT_MARKER, STATUS_CODES, CompareOptions, PairResult
from pyramid_cli.diff.idiff import format_value
from pyramid_cli.imageio.atomic import atomic_path
from pyramid_cli.imageio.colour import linear_to_srgb

__all__ = ["display", "write_html"]

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:1.5em;background:#1e1e1e;color:#ddd}
h1{font-size:1.3em} .pair{border:1px solid #444;margin:1em 0;padding:.6em 1em;border-radius:6px}
.pair.failure,.pair.size,.pair.file,.pair.missing,.pair.extra{border-color:#c0392b}
.pair.warning{border-color:#d4ac0d} .pair.match{border-color:#27ae60}
.badge{font-weight:bold;padding:0 .4em;border-radius:3px;color:#000}
.failure .badge,.size .badge,.file .badge,.missing .badge,.extra .badge{background:#e74c3c}
.warning .badge{background:#f1c40f} .match .badge{background:#2ecc71}
.tiles{display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start}
figure{margin:0} figcaption{font-size:.85em;color:#aaa}
img{image-rendering:pixelated;max-width:360px;min-width:128px;background:#000;border:1px solid #555}
img.flip{cursor:pointer} table{border-collapse:collapse;font-size:.85em}
td,th{padding:1px 8px;text-align:left;border-bottom:1px solid #333} code{color:#9cf}
"""

_JS = """
function flip(img){
  var showB = img.dataset.showing !== 'B';
  img.src = showB ? img.dataset.b : img.dataset.a;
  img.dataset.showing = showB ? 'B' : 'A';
  var cap = document.getElementById(img.id + '-cap');
  if (cap) cap.textContent = (showB ? 'B (reference)' : 'A (output)') + ' \\u2014 click to flip';
}
document.querySelectorAll('img.flip').forEach(function(img){
  img.addEventListener('click', function(){ flip(img); });
  img.addEventListener('keydown', function(e){
    if (e.key === ' ' || e.key === 'Enter') { flip(img); e.preventDefault(); }
  });
});
document.getElementById('flip-all').addEventListener('click', function(){
  document.querySelectorAll('img.flip').forEach(flip);
});
if (location.hash === '#B') document.querySelectorAll('img.flip').forEach(flip);  // index.html#B opens on B
"""


def _srgb(x: np.ndarray) -> np.ndarray:
    """Display colours of linear values: clamped to [0, 1], sRGB-encoded (float64)."""
    return linear_to_srgb(np.clip(x, 0.0, 1.0))


def _alpha_index(names: Sequence[str]) -> int:
    for i, n in enumerate(names):
        if n.upper() in ("A", "ALPHA") or n.upper().endswith(".A"):
            return i
    return 3 if len(names) == 4 else -1


def _colour(px: np.ndarray, names: Sequence[str]) -> np.ndarray:
    ai = _alpha_index(names)
    cols = [i for i in range(px.shape[2]) if i != ai][:3]
    if not cols:
        cols = [0]
    rgb = px[..., cols]
    if rgb.shape[2] < 3:
        rgb = np.repeat(rgb[..., :1], 3, axis=2)
    return rgb


def display(px: np.ndarray, names: Sequence[str], encoded: bool) -> np.ndarray:
    """Tone-map pixels for the screen: ``(H, W, 3)`` display colours in [0, 1].

    Parameters
    ----------
    px : numpy.ndarray
        ``(H, W, C)`` values.
    names : sequence of str
        Channel names (the alpha channel is left out of the picture).
    encoded : bool
        True for stored integer code values (shown as they are); False for
        linear values (clamped and sRGB-encoded). NaN shows black, +Inf white.

    Returns
    -------
    numpy.ndarray
        float64 ``(H, W, 3)`` display colours.
    """
    rgb = np.nan_to_num(_colour(np.asarray(px, dtype=np.float64), names), nan=0.0, posinf=1.0, neginf=0.0)
    return np.clip(rgb, 0.0, 1.0) if encoded else _srgb(rgb)


def _amplified(err: np.ndarray) -> tuple[np.ndarray, float]:
    finite = err[np.isfinite(err)]
    top = float(finite.max()) if finite.size else 0.0
    gain = 1.0 / top if top > 0 else 1.0
    out = np.where(np.isfinite(err), err * gain, 1.0)
    return np.clip(out, 0.0, 1.0), gain


def _pictures(pr: PairResult, opts: CompareOptions, img_dir: str, key: str) -> list[tuple[str, str, str]]:
    """Write the PNGs of one pair; (kind, file name, caption) for each."""
    from pyramid_cli.diff.goldens import read_pixels
    from pyramid_cli.imageio import raw as io_raw

    tiles: list[tuple[str, str, str]] = []
    sub, mip = (pr.levels[0].subimage, pr.levels[0].miplevel) if pr.levels else (0, 0)
    px: dict[str, tuple[np.ndarray, list[str]]] = {}
    for side, path in (("a", pr.path_a), ("b", pr.path_b)):
        if not path or not os.path.isfile(path):
            continue
        try:
            pixels, names = read_pixels(path, opts, sub, mip)
            encoded = (not opts.linear) and io_raw.read_level(path, sub, mip).pixel_type.startswith(("uint", "int"))
        except PyramidError:
            continue
        px[side] = (pixels, names)
        fname = f"{key}-{side}.png"
        io_raw.write_display_png(os.path.join(img_dir, fname), display(pixels, names, encoded))
        tiles.append((side, fname, "A (output)" if side == "a" else "B (reference)"))
    if "a" in px and "b" in px and px["a"][0].shape == px["b"][0].shape:
        (pa, names), (pb, _) = px["a"], px["b"]
        with np.errstate(invalid="ignore"):
            err = np.abs(pa.astype(np.float64) - pb.astype(np.float64))
        err[np.isnan(err) & ~(np.isnan(pa) & np.isnan(pb))] = np.inf
        err[np.isnan(err)] = 0.0
        colour, gain = _amplified(_colour(err, names))
        io_raw.write_display_png(os.path.join(img_dir, f"{key}-dc.png"), _srgb(colour))
        tiles.append(("dc", f"{key}-dc.png", f"|A-B| colour x{gain:.3g} (white: NaN/Inf)"))
        ai = _alpha_index(names)
        if ai >= 0:
            alpha, again = _amplified(err[..., ai:ai + 1])
            io_raw.write_display_png(os.path.join(img_dir, f"{key}-da.png"), _srgb(np.repeat(alpha, 3, axis=2)))
            tiles.append(("da", f"{key}-da.png", f"|A-B| alpha x{again:.3g}"))
    return tiles


def _stats_table(pr: PairResult) -> str:
    if not pr.levels:
        return ""
    rows = ["<tr><th>subimage</th><th>MIP</th><th>size</th><th>max error</th><th>at (x, y, channel)</th>"
            "<th>mean</th><th>RMS</th><th>PSNR dB</th><th>over warn</th><th>over fail</th><th>verdict</th>"
            + ("<th>mean FLIP</th>" if any(lv.flip is not None for lv in pr.levels) else "") + "</tr>"]
    for lv in pr.levels:
        r = lv.result
        at = f"{r.max_x}, {r.max_y}, {r.max_channel_name}" if r.max_x is not None else "-"
        rows.append(
            f"<tr><td>{lv.subimage}</td><td>{lv.miplevel}</td><td>{r.width}x{r.height}x{r.channels}</td>"
            f"<td>{format_value(r.max_error)}</td><td>{html.escape(at)}</td><td>{format_value(r.mean_error)}</td>"
            f"<td>{format_value(r.rms_error)}</td><td>{format_value(r.psnr)}</td>"
            f"<td>{r.n_warn} ({r.percent(r.n_warn):.3g}%)</td><td>{r.n_fail} ({r.percent(r.n_fail):.3g}%)</td>"
            f"<td>{r.verdict} ({r.rule})</td>"
            + (f"<td>{format_value(lv.flip)}</td>" if lv.flip is not None else "") + "</tr>")
    return "<table>" + "".join(rows) + "</table>"


def write_html(folder: str, results: Sequence[PairResult], opts: CompareOptions, *,
               title: str = "pyramid diff") -> str:
    """Write the report into ``folder`` (created if needed).

    Parameters
    ----------
    folder : str
    results : sequence of PairResult
    opts : CompareOptions
        How the images were read (for the pictures).
    title : str

    Returns
    -------
    str
        The path of ``index.html``.

    Raises
    ------
    OutputError
        The folder or a file in it cannot be written.
    """
    img_dir = os.path.join(folder, "img")
    try:
        os.makedirs(img_dir, exist_ok=True)
        with open(os.path.join(folder, REPORT_MARKER), "w", encoding="utf-8") as f:
            f.write("A pyramid diff --html report: folder comparisons skip this folder.\n")
    except OSError as exc:
        raise OutputError(f"cannot write {folder}: {exc.strerror or exc}") from None
    order = sorted(range(len(results)), key=lambda i: (-STATUS_CODES[results[i].status], i))
    counts: dict[str, int] = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    summary = ", ".join(f"{n} {s}" for s, n in sorted(counts.items(), key=lambda kv: -STATUS_CODES[kv[0]]))
    worst = max((r.exit_code for r in results), default=0)
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"
             f"<p id='summary'>{len(results)} pairs: {html.escape(summary)}; exit code {worst}. "
             f"<button id='flip-all' type='button'>flip all A/B</button></p>"]
    for n, i in enumerate(order):
        pr = results[i]
        key = f"{n:04d}"
        tiles = _pictures(pr, opts, img_dir, key)
        names = {kind: (fname, cap) for kind, fname, cap in tiles}
        figs = []
        if "a" in names and "b" in names:
            a_src, b_src = f"img/{names['a'][0]}", f"img/{names['b'][0]}"
            figs.append(f"<figure><img class='flip' id='p{key}' tabindex='0' src='{a_src}' data-a='{a_src}' "
                        f"data-b='{b_src}' data-showing='A' alt='A and B of {html.escape(pr.name)}'>"
                        f"<figcaption id='p{key}-cap'>A (output) \u2014 click to flip</figcaption></figure>")
            figs.append(f"<figure><img src='{b_src}' alt='B'><figcaption>B (reference)</figcaption></figure>")
        else:
            for kind in ("a", "b"):
                if kind in names:
                    figs.append(f"<figure><img src='img/{names[kind][0]}' alt='{kind}'>"
                                f"<figcaption>{names[kind][1]}</figcaption></figure>")
        for kind in ("dc", "da"):
            if kind in names:
                figs.append(f"<figure><img src='img/{names[kind][0]}' alt='{kind}'>"
                            f"<figcaption>{html.escape(names[kind][1])}</figcaption></figure>")
        refs = ("<br>accepted references: " + ", ".join(f"<code>{html.escape(x)}</code>" for x in pr.references)
                if len(pr.references) > 1 else "")
        parts.append(
            f"<section class='pair {pr.status}' data-status='{pr.status}'><h2><span class='badge'>"
            f"{pr.status.upper()}</span> {html.escape(pr.name)}</h2>"
            f"<p>A <code>{html.escape(pr.path_a or '-')}</code> vs B <code>{html.escape(pr.path_b or '-')}</code>"
            f"{refs}<br>rule: {html.escape(pr.rule)} \u2014 {html.escape(pr.message)}</p>"
            f"{_stats_table(pr)}<div class='tiles'>{''.join(figs)}</div></section>")
    parts.append(f"<script>{_JS}</script></body></html>\n")
    index = os.path.join(folder, "index.html")
    with atomic_path(index) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write("".join(parts))
    return index
