"""viser's web client, served unpacked (issue 17 §4: the 3D view's first frame within 1 s of the page's opening).

viser ships its built client as one HTML file (``viser/client/build/index.html``, :func:`reports.scene.static_client_path`):
the style sheet and the JavaScript (2.5 MB) as one zstd frame written in a base-88 attribute of a loader script,
which at every opening decodes the text, unzips a zstd decoder (WASM) with ``DecompressionStream``, decompresses
the frame and injects the JavaScript as an *inline* module script.  The results page's 3D view is a same-origin
iframe of that file, so all of it ran on the page's own main thread beside plotly, and an inline script is
compiled there too: a performance trace of the results page (``benchmarks/scene_first_frame.py --trace``) showed
the client's module compiled and evaluated on the main thread in one long task each, before the recording was
even fetched.

Here the same bytes are unpacked once per process (base-88, then zstd: the loader's own steps, in Python) and
served as files: ``/viser/index.html`` is a small page that links ``client-<hash>.css``, preloads
``client-<hash>.js`` as a module (fetched and compiled off the main thread while the page parses; the browser
caches it, and its code, across openings: the names carry the content's hash, so they are cached for a year),
compiles ``zstd-<hash>.wasm`` and publishes it as ``globalThis.__viserZstdWasm`` (what the loader did: viser's
``src/zstd.ts`` decodes the ``.viser`` recording with it), then imports the module.  Each file is also kept
gzip-compressed and sent so to a browser that accepts it (the clinic's network: 2.5 MB → 0.7 MB).  Nothing comes
from outside the installed package: a viser whose file does not have this layout is served as shipped (the
loader then runs as before), with a warning in the log.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import logging
import re
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from fastapi import APIRouter, Request
from fastapi.responses import FileResponse, Response

log = logging.getLogger(__name__)

#: the loader's base-88 alphabet: printable ASCII without ``" & < > ' ``` (viser's vite-plugin-compress-html.mts)
B88_ALPHABET = "".join(c for c in map(chr, range(0x21, 0x7F)) if c not in "\"&<>'`")
_PAYLOAD = re.compile(r'<script data-p="([^"]*)" data-ss="(\d+)" data-cs="(\d+)"')
_WASM = re.compile(r'const gzWasm=("[^"]*")')
_HEAD_KEEP = re.compile(r"<link\s+rel=\"icon\"[^>]*>|<meta name=\"(?:viewport|theme-color|description)\"[^>]*>")
#: a year: the assets' names carry their content's hash
IMMUTABLE = "public, max-age=31536000, immutable"


def b88_decode(text: str) -> bytes:
    """The loader's base-88 decoding: every 5 characters are 4 bytes, big-endian (a last group of k characters is
    k − 1 bytes)."""
    lut = np.zeros(128, dtype=np.uint64)
    lut[[ord(c) for c in B88_ALPHABET]] = np.arange(88, dtype=np.uint64)
    codes = lut[np.frombuffer(text.encode("ascii"), dtype=np.uint8)]
    n, r = divmod(len(codes), 5)
    v = np.zeros(n, dtype=np.uint64)
    for j in range(5):
        v = v * np.uint64(88) + codes[j:5 * n:5]
    out = v.astype(">u4").tobytes()
    if r:
        tail = 0
        for c in codes[5 * n:]:
            tail = tail * 88 + int(c)
        out += tail.to_bytes(r - 1, "big")
    return out


@dataclass(frozen=True)
class Asset:
    name: str
    media_type: str
    body: bytes
    gzipped: bytes


@dataclass(frozen=True)
class Unpacked:
    index_html: bytes
    assets: dict[str, Asset]


def _asset(stem: str, ext: str, media_type: str, body: bytes) -> Asset:
    name = f"{stem}-{hashlib.sha256(body).hexdigest()[:12]}.{ext}"
    return Asset(name, media_type, body, gzip.compress(body, compresslevel=6, mtime=0))


def unpack(shipped_html: str) -> Unpacked:
    """The client of ``shipped_html`` (viser's single-file build) as a small page and its three files.  Raises
    ValueError when the file is not laid out as the loader expects (another viser version)."""
    import zstandard

    payload, wasm = _PAYLOAD.search(shipped_html), _WASM.search(shipped_html)
    if payload is None or wasm is None:
        raise ValueError("viser's client file has no base-88 payload and zstd decoder where expected")
    css_n, js_n = int(payload.group(2)), int(payload.group(3))
    raw = zstandard.ZstdDecompressor().decompress(b88_decode(payload.group(1)), max_output_size=css_n + js_n)
    if len(raw) != css_n + js_n:
        raise ValueError(f"viser's client payload is {len(raw)} bytes, its loader says {css_n + js_n}")
    decoder = gzip.decompress(b88_decode(json.loads(wasm.group(1))))
    if decoder[:4] != b"\0asm":
        raise ValueError("viser's client zstd decoder is not WebAssembly")
    css = _asset("client", "css", "text/css; charset=utf-8", raw[:css_n])
    js = _asset("client", "js", "text/javascript; charset=utf-8", raw[css_n:])
    zstd = _asset("zstd", "wasm", "application/wasm", decoder)
    head = "\n".join(m.group(0) for m in _HEAD_KEEP.finditer(shipped_html))
    # the loader's two jobs, in its order: the zstd decoder published on globalThis, then the app's module
    boot = (f'globalThis.__viserZstdWasm = await WebAssembly.compileStreaming(fetch("/viser/{zstd.name}"));'
            f'await import("/viser/{js.name}");')
    page = ('<!doctype html>\n<html lang="en">\n<head>\n<meta charset="utf-8" />\n'
            f"{head}\n<title>Viser</title>\n"
            f'<link rel="stylesheet" href="/viser/{css.name}" />\n'
            f'<link rel="modulepreload" href="/viser/{js.name}" />\n'
            f'<script type="module">{boot}</script>\n</head>\n<body>\n'
            '<noscript>You need to enable JavaScript to run this app.</noscript>\n<div id="root"></div>\n'
            "</body>\n</html>\n")
    return Unpacked(page.encode("utf-8"), {a.name: a for a in (css, js, zstd)})


_lock = threading.Lock()
_cache: dict[Path, Unpacked | None] = {}


def unpacked_client(shipped: Path) -> Unpacked | None:
    """:func:`unpack` of the installed client file, once per process; None (the file served as shipped) when it
    cannot be unpacked."""
    with _lock:
        if shipped not in _cache:
            try:
                _cache[shipped] = unpack(shipped.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                log.warning("viser's client is served as shipped (its loader unpacks it in the browser): %s", exc)
                _cache[shipped] = None
        return _cache[shipped]


def _accepts_gzip(request: Request) -> bool:
    return any(part.split(";")[0].strip() == "gzip" for part in request.headers.get("accept-encoding", "").split(","))


def viser_router(shipped: Path) -> APIRouter:
    """``GET /viser/`` and ``/viser/index.html`` (the unpacked page), ``GET /viser/{asset}`` (its files).  Mounted
    before the ``/viser`` static folder, which still answers anything else of the shipped build."""
    router = APIRouter(include_in_schema=False)
    # unpacked beside the start-up (a second or two on a busy machine), not in the first viewer's request
    threading.Thread(target=unpacked_client, args=(shipped,), name="viser-unpack", daemon=True).start()

    @router.get("/viser/")
    @router.get("/viser/index.html")
    def index():
        client = unpacked_client(shipped)
        if client is None:
            return FileResponse(shipped, media_type="text/html")
        return Response(client.index_html, media_type="text/html; charset=utf-8",
                        headers={"Cache-Control": "no-cache"})

    @router.get("/viser/{name}")
    def asset(name: str, request: Request):
        client = unpacked_client(shipped)
        found = client.assets.get(name) if client is not None else None
        if found is None:
            return Response(status_code=404)
        headers = {"Cache-Control": IMMUTABLE, "Vary": "Accept-Encoding"}
        if _accepts_gzip(request):
            return Response(found.gzipped, media_type=found.media_type, headers={**headers, "Content-Encoding": "gzip"})
        return Response(found.body, media_type=found.media_type, headers=headers)

    return router


__all__ = ["B88_ALPHABET", "IMMUTABLE", "Unpacked", "b88_decode", "unpack", "unpacked_client", "viser_router"]
