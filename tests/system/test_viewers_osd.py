"""OpenSeadragon opens our Deep Zoom and IIIF tile sets and shows what their levels hold (issue 27).

OpenSeadragon (npm, pinned in tests/helpers/osd/package-lock.json) runs in headless Chromium on a page served by
a local HTTP server; it opens our ``.dzi``, IIIF 3 ``info.json`` and IIIF 2 ``info.json``, shows the
picture at full, half and quarter size in turn, and each time the screenshot must be the level the tile set holds
for that size (its tiles decoded and stitched here, by the formats' rules, not the writers'): drawn from that level
only, at its place, without a console error, a failed request or a missing tile. That a wrong level fails the
comparison is checked in every view (the level above and below, drawn as the viewer would draw them, are far off).

``vips dzsave`` writes the control tile sets (Deep Zoom and IIIF 3): they prove the harness on the files viewers
are configured for. Both writers' tile sets are shown in one browser (a module fixture); each writer is a test.

What the viewer does, and the comparison follows: it draws a level 1:1 only when told to prefer it
(viewer.html), at the picture's true extent (an odd level's last column may be cut), and the tiles of a layout
without overlap one pixel larger than they are (so a pixel may come from one row or column away).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from helpers.cli import invoke
from helpers.images import write
from helpers.osd.levels import BACKGROUND, IIIF, DeepZoom, error, on_screen, read_rgb
from helpers.osd.viewer import drive, missing, page_url, serving

#: The picture (w, h): odd width, so ⌈n/2⌉ shows at once; 12 Deep Zoom levels, tiles of 254 (+1) and 512 (IIIF).
SIZE = (1501, 999)
#: The viewer's box on screen (w, h).
BOX = (600, 400)
#: The views: (k, x0, y0) shows the picture halved k times, screen pixel (0, 0) at level-k pixel (x0, y0).
VIEWS = [(0, 800, 400),     # full size: across tile corners of both grids
         (1, 171, 120),     # half size: the right and bottom edges, 20 px of background beyond
         (2, -112, -75)]    # quarter size (376 × 250): the whole picture amid the background
#: A view matches its level when its mean error is below MATCH codes and at most 0.1 % of its pixels are off by
#: more than OFF codes (two JPEG decoders may differ by a code; a wrong level, a misplaced or missing tile are off
#: by tens: see WRONG).
MATCH, OFF = 1.0, 8
#: The level above or below, drawn as the viewer would, must be off by more than WRONG codes on average.
WRONG = 5.0
#: The layouts: name → the file OpenSeadragon opens, relative to the tile set's folder.
LAYOUTS = {"dz": "dz.dzi", "iiif3": "iiif3/info.json", "iiif": "iiif/info.json"}


@pytest.fixture(scope="module")
def viewer() -> None:
    """Chromium, node and the npm packages, or a skip naming what is missing (under CI, a failure)."""
    reason = missing()
    if reason:
        if os.environ.get("CI"):
            pytest.fail(f"CI must run the OpenSeadragon tests: {reason}")
        pytest.skip(reason)


@pytest.fixture(scope="module")
def picture(tmp_path_factory) -> Path:
    """An 8-bit sRGB picture with detail at every scale (random blocks of 1, 2, 4 … 64 pixels summed), so that
    each pyramid level differs from its neighbours in every region."""
    path = tmp_path_factory.mktemp("osd") / "in.png"
    w, h = SIZE
    rng = np.random.default_rng(27)
    px = np.zeros((h, w, 3), np.float32)
    for s in (1, 2, 4, 8, 16, 32, 64):
        blocks = rng.random((-(-h // s), -(-w // s), 3), np.float32)
        px += np.repeat(np.repeat(blocks, s, 0), s, 1)[:h, :w]
    px = np.clip((px / 7 - 0.5) * 3 + 0.5, 0, 1)
    return write(path, np.round(px * 255).astype(np.uint8), "uint8")


def dzsave(src: Path, out: Path, url: str) -> tuple[list[str], bool]:
    """The control: Deep Zoom and IIIF 3 written by libvips (IIIF 2 differs only in the names), the IIIF id the
    address ``url`` serves ``out`` at; the layouts, and whether the id is set."""
    pyvips = pytest.importorskip("pyvips")
    image = pyvips.Image.new_from_file(str(src))
    layouts = ["dz", "iiif3"]
    for layout in layouts:
        image.dzsave(str(out / layout), layout=layout, id=url)
    return layouts, True


def ours(src: Path, out: Path, url: str) -> tuple[list[str], bool]:
    """Ours: `pyramid tiles` with the defaults, the layout from the name or --layout, the IIIF id ``url`` (as vips
    dzsave's --id: the folder's address) where the command takes an --id; the layouts, and whether the id is set."""
    from pyramid_cli.cli import main

    command = main.commands.get("tiles") if hasattr(main, "commands") else None
    has_id = command is not None and any("--id" in p.opts for p in command.params)
    named = ["--id", url] if has_id else []
    for args in ([src, out / "dz.dzi"], ["--layout", "iiif3", *named, src, out / "iiif3"],
                 ["--layout", "iiif", *named, src, out / "iiif"]):
        r = invoke("tiles", *args)
        assert r.exit_code == 0, f"pyramid tiles {' '.join(map(str, args))}: exit {r.exit_code}: {r.output}"
    return list(LAYOUTS), has_id


WRITERS = {"vips-dzsave": dzsave, "pyramid": ours}


def check_case(layout: str, found: Path, answer: dict, iiif_id: str | None = None) -> list[str]:
    """What is wrong with one tile set as the viewer showed it (an empty list when nothing is); ``iiif_id``: the
    id an info.json must name."""
    problems = [f"{layout}: {kind}: {answer[kind]}" for kind in
                ("error", "console", "pageErrors", "failedRequests", "badResponses", "osdEvents") if answer[kind]]
    if len(answer["views"]) != len(VIEWS):
        return problems + [f"{layout}: {len(answer['views'])} views shown, not {len(VIEWS)}"]
    try:
        tiles = DeepZoom(found) if layout == "dz" else IIIF(found)
    except (OSError, ValueError, KeyError) as e:
        return problems + [f"{layout}: {found} unreadable: {e}"]
    if isinstance(tiles, IIIF):
        key = "id" if tiles.version == 3 else "@id"
        named = tiles.info.get(key)
        if not isinstance(named, str) or (iiif_id is not None and named != iiif_id):
            problems.append(f"{layout}: info.json's {key} is {named!r}, not {iiif_id or 'a string'!r}")
    # scale factors the viewer has: Deep Zoom every level; IIIF the info.json's (OpenSeadragon's levels 0…max)
    top = tiles.top if isinstance(tiles, DeepZoom) else int(np.log2(max(tiles.scale_factors)))
    has = (lambda k: 0 <= k <= tiles.top) if isinstance(tiles, DeepZoom) else (lambda k: 2 ** k in tiles.scale_factors)
    # OpenSeadragon draws tiles without overlap one pixel larger (to hide seams): one row and column of each repeat
    reach = 0 if isinstance(tiles, DeepZoom) and tiles.overlap > 0 else 1
    try:
        levels = {k: tiles.level(k) for k in range(len(VIEWS) + 1) if has(k)}
    except AssertionError as e:     # a tile missing, or of a size the grid does not give
        return problems + [f"{layout}: {e}"]
    w, h = BOX
    for (k, x0, y0), seen in zip(VIEWS, answer["views"], strict=True):
        where = f"{layout} at 1/{2 ** k}"
        if seen["maxLevel"] != top or seen["levels"] != [top - k] or abs(seen["imageZoom"] - 0.5 ** k) > 1e-9:
            problems.append(f"{where}: the viewer drew levels {seen['levels']} of 0…{seen['maxLevel']} at zoom "
                            f"{seen['imageZoom']}, not level {top - k} of 0…{top} at {0.5 ** k}")
        if k not in levels:
            problems.append(f"{where}: the tile set has no such level")
            continue
        shot = read_rgb(Path(seen["shot"]))
        if shot.shape[:2] != (h, w):
            problems.append(f"{where}: a screenshot of {shot.shape[1]}×{shot.shape[0]}, not {w}×{h}")
            continue
        extent = (SIZE[0] / 2 ** k, SIZE[1] / 2 ** k)     # the picture on screen
        screen = on_screen(levels[k], x0, y0, w, h, reach=reach, extent=extent)
        e = error(shot, screen, reach)
        mean, off = e.mean(), np.mean(e > OFF)
        if not mean < MATCH or off > 0.001:
            problems.append(f"{where}: the screenshot is not the level: mean error {mean:.2f} codes, "
                            f"{off:.2%} of the pixels off by more than {OFF}")
        picture_px = ~np.all(screen[0][reach:reach + h, reach:reach + w] == BACKGROUND, -1)
        for other in (k - 1, k + 1):    # the harness can tell: a neighbouring level is far off
            if other in levels:
                wrong = error(shot, on_screen(levels[other], x0, y0, w, h, 2.0 ** (other - k), reach, extent), reach)
                if not wrong[picture_px].mean() > WRONG:
                    problems.append(f"{where}: level 1/{2 ** other} would pass too (error "
                                    f"{wrong[picture_px].mean():.2f} codes): the comparison cannot tell levels")
    return problems


@pytest.fixture(scope="module")
def shown(viewer, picture, tmp_path_factory) -> dict[str, list[str] | BaseException]:
    """Every writer's tile sets written and shown in one browser (its launch is most of the time): writer → what is
    wrong with them (an empty list when nothing is), or why the writer could not write them."""
    root = tmp_path_factory.mktemp("osd-tiles")
    w, h = BOX
    results: dict[str, list[str] | BaseException] = {}
    written: dict[str, tuple[list[str], bool]] = {}
    cases = []
    with serving(root) as server:
        for writer, write in WRITERS.items():
            (root / writer).mkdir()
            try:
                written[writer] = write(picture, root / writer, f"{server.url}/data/{writer}")
            except (Exception, pytest.skip.Exception) as e:
                results[writer] = e
                continue
            layouts, has_id = written[writer]
            cases += [{"name": f"{writer}/{layout}",
                       "url": page_url(server, f"{writer}/{LAYOUTS[layout]}", w, h, rebase=not has_id),
                       "views": [{"x": x0 * 2 ** k, "y": y0 * 2 ** k, "width": w * 2 ** k, "height": h * 2 ** k,
                                  "shot": str(root / f"{writer}-{layout}-{k}.png")} for k, x0, y0 in VIEWS]}
                      for layout in layouts]
        answers = dict(zip([c["name"] for c in cases], drive(cases, w, h), strict=True))
    for writer, (layouts, has_id) in written.items():
        problems = [f"HTTP {code} {path}" for code, path in server.requests if code not in (200, 304)
                    and (path.startswith(f"/data/{writer}/") or not path.startswith("/data/"))]
        for layout in layouts:
            served = f"{server.url}/data/{writer}/{layout}" if has_id else None
            problems += check_case(layout, root / writer / LAYOUTS[layout], answers[f"{writer}/{layout}"], served)
        results[writer] = problems
    return results


@pytest.mark.cli
@pytest.mark.slow
def test_openseadragon_shows_every_level_as_stored(shown):
    """Ours (``pyramid tiles``) and ``vips dzsave``'s, the control that proves the harness, in one test: the
    module's one browser is shared (two tests could land on two pytest-xdist workers, each launching it)."""
    failures = []
    for writer, problems in shown.items():
        if isinstance(problems, BaseException):    # the writer could not write its tile sets
            raise problems
        failures += [f"{writer}: {p}" for p in problems]
    assert set(shown) == set(WRITERS) and not failures, "\n".join(failures)
