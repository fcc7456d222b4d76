"""viser's client served unpacked (app/web/viser_client.py): the files the server sends are byte for byte what viser's
own loader makes of its shipped single-file build in Chromium (the loader is the reference: its injected module
script, its style element and the zstd decoder it publishes), the page links them, and each is sent with its media
type, gzip-compressed when the browser accepts it, and cached by its content's hash.  A client file of another
layout is served as shipped.  The 3D view drawing with it is tests/app/web/test_browser_scene.py."""

from __future__ import annotations

import gzip
import hashlib
import random
import re

import pytest
from test_browser_e2e import open_page, server  # noqa: F401

from app.web.viser_client import B88_ALPHABET, b88_decode, unpack, unpacked_client
from reports.scene import static_client_path


def _b88_encode(data: bytes) -> str:
    """Encoder of the format the loader reads (viser's vite-plugin-compress-html.mts, toBase88): 4 bytes → 5
    characters, most significant first; a last group of r bytes → r + 1 characters."""
    out = []
    for i in range(0, len(data) - len(data) % 4, 4):
        v = int.from_bytes(data[i:i + 4], "big")
        out.append("".join(B88_ALPHABET[(v // 88 ** k) % 88] for k in range(4, -1, -1)))
    r = len(data) % 4
    if r:
        v = int.from_bytes(data[-r:], "big")
        out.append("".join(B88_ALPHABET[(v // 88 ** k) % 88] for k in range(r, -1, -1)))
    return "".join(out)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4, 5, 1000, 1003])
def test_base88_decodes_what_the_format_encodes(n):
    data = bytes(random.Random(n).getrandbits(8) for _ in range(n)) if n < 1000 else b"\xff" * n
    assert b88_decode(_b88_encode(data)) == data
    assert len(B88_ALPHABET) == 88 and not set("\"&<>'`") & set(B88_ALPHABET)


def test_a_client_file_of_another_layout_is_served_as_shipped(tmp_path):
    with pytest.raises(ValueError):
        unpack("<!doctype html><html><script type=module src=app.js></script></html>")
    other = tmp_path / "index.html"
    other.write_text("<!doctype html><html><body>viser 2</body></html>", encoding="utf-8")
    assert unpacked_client(other) is None

    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from app.web.viser_client import viser_router

    app = FastAPI()
    app.include_router(viser_router(other))
    with TestClient(app) as c:
        assert c.get("/viser/index.html").text == other.read_text(encoding="utf-8")
        assert c.get("/viser/client-0123456789ab.js").status_code == 404


def test_the_page_links_its_files_sent_compressed_and_cached(client):
    page = client.get("/viser/index.html", params={"playbackPath": "/api/v1/sessions/3/scene.viser"})
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "data-p=" not in page.text  # not the packed build
    names = re.findall(r'"/viser/((?:client|zstd)-[0-9a-f]{12}\.(?:js|css|wasm))"', page.text)
    assert sorted(n.rsplit(".", 1)[1] for n in set(names)) == ["css", "js", "wasm"]
    assert "__viserZstdWasm" in page.text  # the decoder published as the loader did (viser's src/zstd.ts reads it)
    media = {"js": "text/javascript", "css": "text/css", "wasm": "application/wasm"}
    for name in set(names):
        r = client.get(f"/viser/{name}", headers={"Accept-Encoding": "gzip"})
        assert r.status_code == 200 and r.headers["content-type"].startswith(media[name.rsplit(".", 1)[1]])
        assert r.headers["content-encoding"] == "gzip" and "immutable" in r.headers["cache-control"]
        assert r.headers["vary"] == "Accept-Encoding"
        assert "content-security-policy" in r.headers  # viser's CSP, as on the shipped file
        plain = client.get(f"/viser/{name}", headers={"Accept-Encoding": "identity"})
        assert "content-encoding" not in plain.headers
        assert plain.content == r.content  # (httpx undid the gzip)
        assert hashlib.sha256(plain.content).hexdigest()[:12] == name.split("-")[1].split(".")[0]
        assert len(gzip.compress(plain.content)) < len(plain.content)
    assert client.get("/viser/client-000000000000.js").status_code == 404
    assert client.get("/viser/index.html", params={"playbackPath": "http://evil.example/x.viser"}).status_code == 400


def test_the_served_files_are_what_viser_s_loader_unpacks_in_chromium(browser, server):  # noqa: F811
    """The shipped file opened in Chromium (same origin, routed in): its loader decodes the payload, injects the
    style and the module script and publishes the zstd decoder; their bytes equal the files the server sends."""
    shipped = static_client_path().read_bytes()
    context, page, _ = open_page(browser, "en-GB")
    try:
        context.route("**/viser-shipped.html", lambda route: route.fulfill(body=shipped, content_type="text/html"))
        page.goto(f"{server}/viser-shipped.html")
        page.wait_for_function("() => [...document.head.querySelectorAll('script[type=module]')]"
                               ".some((s) => s.textContent.length > 1e6) && globalThis.__viserZstdWasm", timeout=120_000)
        loader = page.evaluate("""async () => {
            const hex = async (text) => [...new Uint8Array(await crypto.subtle.digest('SHA-256',
                new TextEncoder().encode(text)))].map((b) => b.toString(16).padStart(2, '0')).join('');
            const js = [...document.head.querySelectorAll('script[type=module]')].find((s) => s.textContent.length > 1e6);
            const css = [...document.head.querySelectorAll('style')].map((s) => s.textContent).find((t) => t.length > 1e5);
            return { js: await hex(js.textContent), css: await hex(css),
                     wasm: WebAssembly.Module.exports(globalThis.__viserZstdWasm).map((e) => e.name).sort() };
        }""")
        index = context.request.get(f"{server}/viser/index.html").text()
        served = {}
        for name in re.findall(r'"/viser/((?:client|zstd)-[0-9a-f]{12}\.(?:js|css|wasm))"', index):
            served[name.rsplit(".", 1)[1]] = context.request.get(f"{server}/viser/{name}").body()
        assert hashlib.sha256(served["js"]).hexdigest() == loader["js"]
        assert hashlib.sha256(served["css"]).hexdigest() == loader["css"]
        ours = page.evaluate("""async (url) => WebAssembly.Module.exports(await WebAssembly.compileStreaming(fetch(url)))
                                  .map((e) => e.name).sort()""", f"/viser/{[n for n in re.findall(r'zstd-[0-9a-f]{12}.wasm', index)][0]}")
        assert ours == loader["wasm"] and "ZSTD_decompress" in ours
    finally:
        context.close()
