"""The browser side of the viewer tests: what must be installed, a local HTTP server, and ``drive.js``'s runs."""

from __future__ import annotations

import http.server
import json
import os
import shutil
import subprocess
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlsplit

#: This folder: viewer.html, drive.js, the npm manifest and (once installed) node_modules.
FOLDER = Path(__file__).resolve().parent
#: The npm packages drive.js and viewer.html load.
PACKAGES = ("openseadragon", "playwright-core")
#: The command that installs them.
INSTALL = "npm ci --prefix tests/helpers/osd"


def missing() -> str | None:
    """Why the viewer tests cannot run here (a sentence naming what to install), or None when they can."""
    if not (shutil.which("chromium") or shutil.which("chromium-browser")):
        return "chromium is not on PATH (apt-get install -y chromium)"
    if not shutil.which("node"):
        return "node is not on PATH (Node.js 20 or newer, with npm)"
    absent = [p for p in PACKAGES if not (FOLDER / "node_modules" / p / "package.json").is_file()]
    if absent:
        return f"{', '.join(absent)} not installed in tests/helpers/osd/node_modules: run `{INSTALL}` (or make test)"
    return None


@dataclass
class Server:
    """A threaded HTTP server on 127.0.0.1 (a free port): ``/osd/…`` is this folder, ``/data/…`` is ``root``.
    ``requests`` lists every request as ``(status, path)``."""

    root: Path
    requests: list[tuple[int, str]] = field(default_factory=list)
    url: str = ""

    def handler(self) -> type[http.server.SimpleHTTPRequestHandler]:
        server = self

        class Handler(http.server.SimpleHTTPRequestHandler):
            def translate_path(self, path: str) -> str:
                parts = unquote(urlsplit(path).path).split("/")
                if ".." in parts or len(parts) < 3:
                    return str(server.root / "missing")
                top = {"osd": FOLDER, "data": server.root}.get(parts[1], server.root / "missing")
                return str(top.joinpath(*parts[2:]))

            def log_request(self, code="-", size="-") -> None:
                server.requests.append((int(code) if str(code).isdigit() else 0, unquote(self.path)))

            def log_message(self, format, *args) -> None:  # noqa: A002 (the base class's name)
                pass

        return Handler


@contextmanager
def serving(root: Path) -> Iterator[Server]:
    """Serve ``root`` (and this folder) for the duration of the block."""
    server = Server(root)
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), server.handler())
    server.url = f"http://127.0.0.1:{httpd.server_port}"
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join()


def page_url(server: Server, tiles: str, width: int, height: int, rebase: bool = False) -> str:
    """The viewer page showing ``tiles`` (a path under ``/data``: a .dzi or an info.json) in a width × height box;
    ``rebase``: the page points an info.json's id at the folder it was served from (see viewer.html)."""
    return f"{server.url}/osd/viewer.html?tiles=/data/{tiles}&width={width}&height={height}&rebase={int(rebase)}"


def drive(cases: list[dict], width: int, height: int, timeout: float = 120) -> list[dict]:
    """Run drive.js once (one Chromium) over ``cases`` (see drive.js for their form); its answer per case."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    with tempfile.TemporaryDirectory(prefix="osd-profile-") as profile:
        plan = {"chromium": chromium, "profile": profile, "width": width, "height": height, "cases": cases}
        env = {**os.environ, "PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD": "1"}
        r = subprocess.run(["node", str(FOLDER / "drive.js")], input=json.dumps(plan), capture_output=True,
                           text=True, timeout=timeout, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"drive.js failed ({r.returncode}): {r.stderr[-3000:]}")
    return json.loads(r.stdout)["cases"]
