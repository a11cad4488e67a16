"""The local web server of ``notchfit review``: the page, its static files and a small JSON API.

Built on the standard library's :class:`http.server.ThreadingHTTPServer`
(docs/review.md says why). It listens on 127.0.0.1 only and refuses any
request whose peer is not the local machine, whose ``Host`` header names
another host (a web page elsewhere reaching it through DNS rebinding) or
whose ``Origin`` is another site. Every file the page needs ships in the
package (``notchfit/review/static``): nothing is fetched from the internet.

API (``E`` the experiment's index, ``S`` the sample id):

======================================  ============================================
``GET  /api/study``                     experiments, samples and their corner counts
``GET  /api/sample/E/S``                the sample's corners and its image's pyramid
``GET  /api/tile/E/S/L/X/Y.jpg``        tile (X, Y) of pyramid level L
``GET  /api/thumb/E/S.jpg``             the sample's thumbnail
``GET  /api/fit/E/S``                   the live free-θ fit (residual per corner)
``GET  /api/angles/E/S``                the angles by hand and the cut-face lines
``GET  /api/changes?since=N&client=C``  corners changed by other tabs since change N
``POST /api/edit``                      one action on one corner (JSON body)
``POST /api/angles/E``                  write the experiment's angles.csv
======================================  ============================================
"""

from __future__ import annotations

import ipaddress
import json
import re
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from urllib.parse import parse_qs, urlsplit

from .images import PyramidCache

__all__ = ["ReviewServer", "make_server"]

#: The only address the server binds to.
HOST = "127.0.0.1"
_STATIC_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
                 ".css": "text/css; charset=utf-8", ".png": "image/png", ".svg": "image/svg+xml"}
_LOCAL_NAMES = ("127.0.0.1", "localhost", "[::1]")
_MAX_BODY = 64 * 1024


def _is_loopback(addr: str) -> bool:
    try:
        return ipaddress.ip_address(addr.split("%")[0]).is_loopback
    except ValueError:
        return False


class ReviewServer(ThreadingHTTPServer):
    """A threading HTTP server holding the review session and the image cache."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, port: int, session, *, prefetch: int = 1, cache_images: int = 4):
        super().__init__((HOST, int(port)), ReviewHandler)
        self.session = session
        self.images = PyramidCache(cache_images)
        self.prefetch = int(prefetch)
        self.shutting_down = threading.Event()

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server_address[1]}/"

    def image_path(self, exp: int, sample: int):
        r = self.session.get(exp)
        paths = r.exp.image_paths
        if paths is None or paths[r.index(sample)] is None:
            raise KeyError(f"{r.exp.name}: sample {sample} has no image")
        return paths[r.index(sample)]

    def neighbours(self, exp: int, sample: int) -> list:
        """Image paths of the samples around ``sample`` (built ahead of a switch)."""
        r = self.session.get(exp)
        i, paths = r.index(sample), r.exp.image_paths or []
        return [paths[j] for d in range(1, self.prefetch + 1) for j in (i + d, i - d) if 0 <= j < len(paths)]


def make_server(session, port: int = 0, **kw) -> ReviewServer:
    """A :class:`ReviewServer` on 127.0.0.1 (``port`` 0: any free port)."""
    return ReviewServer(port, session, **kw)


class ReviewHandler(BaseHTTPRequestHandler):
    """One request: the local checks, then a route of the API or a static file."""

    server: ReviewServer
    protocol_version = "HTTP/1.1"

    def log_message(self, fmt, *args):  # noqa: D102 - quiet: the terminal shows the address only
        return

    # ------------------------------------------------------------------ checks and replies
    def _refusal(self) -> str | None:
        """Why the request is refused (not local), or None."""
        if not _is_loopback(self.client_address[0]):
            return f"refused: {self.client_address[0]} is not this machine"
        host = (self.headers.get("Host") or "").strip().lower()
        port = str(self.server.server_address[1])
        if host not in {f"{n}:{port}" for n in _LOCAL_NAMES}:
            return f"refused: Host {host!r} is not this server's local address"
        origin = self.headers.get("Origin")
        if origin is not None and origin.lower() not in {f"http://{n}:{port}" for n in _LOCAL_NAMES}:
            return f"refused: Origin {origin!r} is another site"
        return None

    def _send(self, status: int, body: bytes, ctype: str, *, cache: bool = False) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "max-age=3600" if cache else "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, obj, status: int = 200) -> None:
        self._send(status, json.dumps(obj, allow_nan=False).encode(), "application/json")

    def _error(self, status: int, message: str) -> None:
        self._json({"error": message}, status)

    def _guarded(self, fn) -> None:
        why = self._refusal()
        if why is not None:
            self._error(HTTPStatus.FORBIDDEN, why)
            return
        try:
            fn()
        except (BrokenPipeError, ConnectionResetError):
            return                                  # the tab went away (a tile no longer in view)
        except KeyError as exc:
            self._error(HTTPStatus.NOT_FOUND, str(exc.args[0]) if exc.args else "not found")
        except (ValueError, OSError) as exc:
            self._error(HTTPStatus.BAD_REQUEST, str(exc))
        except Exception as exc:  # noqa: BLE001 - the page gets the reason; the server keeps serving
            self._error(HTTPStatus.INTERNAL_SERVER_ERROR, f"{type(exc).__name__}: {exc}")

    # ------------------------------------------------------------------ GET
    def do_GET(self):  # noqa: N802 - http.server's name
        self._guarded(self._get)

    def _get(self) -> None:
        url = urlsplit(self.path)
        path, query = url.path, parse_qs(url.query)
        session = self.server.session
        if path in ("/", "/index.html"):
            return self._static("index.html")
        if path == "/favicon.ico":
            return self._send(HTTPStatus.NO_CONTENT, b"", "image/x-icon")
        if path.startswith("/static/"):
            return self._static(path[len("/static/"):])
        if path == "/api/study":
            return self._json(session.overview())
        if path == "/api/changes":
            since = int(query.get("since", ["0"])[0])
            return self._json(session.changes_since(since, query.get("client", [None])[0]))
        m = re.fullmatch(r"/api/(sample|fit|angles)/(\d+)/(-?\d+)", path)
        if m:
            return self._sample_route(m.group(1), int(m.group(2)), int(m.group(3)))
        m = re.fullmatch(r"/api/tile/(\d+)/(-?\d+)/(\d+)/(\d+)/(\d+)\.jpg", path)
        if m:
            e, s, level, tx, ty = (int(g) for g in m.groups())
            data = self.server.images.get(self.server.image_path(e, s)).tile_jpeg(level, tx, ty)
            return self._send(200, data, "image/jpeg", cache=True)
        m = re.fullmatch(r"/api/thumb/(\d+)/(-?\d+)\.jpg", path)
        if m:
            data = self.server.images.thumbnail(self.server.image_path(int(m.group(1)), int(m.group(2))))
            return self._send(200, data, "image/jpeg", cache=True)
        raise KeyError(f"no such page: {path}")

    def _sample_route(self, what: str, e: int, s: int) -> None:
        session = self.server.session
        if what == "fit":
            return self._json(session.fit(e, s))
        if what == "angles":
            return self._json(session.angles(e, s))
        out = session.sample(e, s)
        try:
            path = self.server.image_path(e, s)
        except KeyError:
            out["image"] = None
        else:
            out["image"] = self.server.images.get(path).info()
            self.server.images.prefetch(self.server.neighbours(e, s))
        return self._json(out)

    def _static(self, name: str) -> None:
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", name) or name.startswith("."):
            raise KeyError(f"no such file: {name}")
        res = resources.files(__package__).joinpath("static", name)
        if not res.is_file():
            raise KeyError(f"no such file: {name}")
        ext = name[name.rfind("."):]
        self._send(200, res.read_bytes(), _STATIC_TYPES.get(ext, "application/octet-stream"))

    # ------------------------------------------------------------------ POST
    def do_POST(self):  # noqa: N802 - http.server's name
        self._guarded(self._post)

    def _body(self) -> dict:
        n = int(self.headers.get("Content-Length") or 0)
        if not 0 < n <= _MAX_BODY:
            raise ValueError("a JSON body of at most 64 kB is expected")
        try:
            body = json.loads(self.rfile.read(n))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"bad JSON: {exc}") from None
        if not isinstance(body, dict):
            raise ValueError("the body must be a JSON object")
        return body

    def _post(self) -> None:
        path = urlsplit(self.path).path
        session = self.server.session
        if path == "/api/edit":
            b = self._body()
            try:
                out = session.edit(int(b["exp"]), int(b["sample"]), int(b["point"]), str(b["action"]),
                                   u=b.get("u"), v=b.get("v"), row=b.get("row"), version=b.get("version"),
                                   client=b.get("client"))
            except (TypeError, KeyError) as exc:
                raise ValueError(f"bad edit: {exc}") from None
            return self._json(out)
        m = re.fullmatch(r"/api/angles/(\d+)", path)
        if m:
            return self._json(session.write_angles(int(m.group(1))))
        raise KeyError(f"no such action: {path}")
