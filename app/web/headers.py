"""Security headers on every answer, as a plain ASGI middleware (:class:`SecurityHeaders`).

Plain ASGI rather than ``@app.middleware("http")``: Starlette's function middleware re-streams every request
body through an extra task and memory stream, a cost every upload chunk paid on the event loop that all
other requests share (``benchmarks/load.py``); this one only edits the response's start message.

What it sets: ``X-Content-Type-Options: nosniff`` and ``Referrer-Policy: no-referrer`` everywhere (unless the
route set them); every ``/api/`` answer is ``Cache-Control: no-store`` (ASVS 8.2.1): they carry patient data,
reports or CSRF tokens, and no browser cache or proxy may keep a copy (a shared ward computer).  Outside
development every answer carries ``Strict-Transport-Security`` (one year, subdomains): once a browser has
reached ChakaMo over HTTPS it never again sends a cookie over plain HTTP.  A Content-Security-Policy on the
UI (:data:`UI_CSP`, plus ``X-Frame-Options``), on ``/docs`` (:data:`DOCS_CSP`, ``X-Frame-Options: DENY``), on
``report.html`` (:data:`REPORT_HTML_CSP`, set by its route) and on viser's client (:data:`VISER_CSP`), which may play only
this server's session scenes: a ``playbackPath`` outside :data:`PLAYBACK_PREFIX` (after decoding), or given
twice (the server and viser's client could read different ones), answers 400.
"""

from __future__ import annotations

import posixpath
from urllib.parse import parse_qsl, unquote

from starlette.datastructures import MutableHeaders
from starlette.responses import JSONResponse

#: Content-Security-Policy of the UI (``/``, ``/static``): scripts and data only from this origin; plotly
#: sets inline styles; the 3D view is an iframe of ``/viser``; no other site may frame the app.
UI_CSP = ("default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
          "font-src 'self' data:; connect-src 'self'; frame-src 'self'; frame-ancestors 'self'; base-uri 'none'; "
          "form-action 'self'; object-src 'none'")
#: viser's client runs scene messages that may carry JavaScript (``RunJavascriptMessage``): it may fetch only
#: from this origin, so the only scenes it can play are the ones this server stored (never a crafted file
#: from another site, which would run with the user's session).
VISER_CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline' 'unsafe-eval' blob:; "
             "style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; font-src 'self' data:; "
             "connect-src 'self' data: blob:; worker-src 'self' blob:; frame-ancestors 'self'; base-uri 'none'; "
             "object-src 'none'")
#: Swagger UI at ``/docs`` (its page inlines the script that starts it, and reads ``/openapi.json``): no other
#: site may frame it (issue 16, finding 10e: a framed /docs could be clickjacked)
DOCS_CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
            "img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'; "
            "object-src 'none'")
#: ``report.html`` (served by :mod:`app.web.api.artefacts`) holds text typed by people, so it runs sandboxed in
#: an opaque origin (no cookie, no API); everything it needs is inline (plotly.js, its figures, the CSS), so
#: it may load nothing and reach nothing: no fetch, no form, no frame, no image from the network (finding
#: 10f: the sandbox alone allowed network access).  ``'unsafe-eval'``: plotly.js builds some functions at
#: run time; it gives nothing to reach, since nothing may be fetched.
REPORT_HTML_CSP = ("sandbox allow-scripts allow-popups allow-downloads; default-src 'none'; "
                   "script-src 'unsafe-inline' 'unsafe-eval'; style-src 'unsafe-inline'; img-src data: blob:; "
                   "font-src data:; connect-src 'none'; form-action 'none'; frame-src 'none'; worker-src 'none'; "
                   "base-uri 'none'; object-src 'none'; frame-ancestors 'self'")
#: the one kind of recording the 3D view is allowed to play
PLAYBACK_PREFIX = "/api/v1/sessions/"
HSTS = "max-age=31536000; includeSubDomains"


def host_allowed(host: str, patterns: tuple[str, ...]) -> bool:
    """Whether ``host`` (a ``Host`` header: name or ``[v6]``, optional ``:port``) matches one of ``patterns``
    (exact names, ``*.domain`` for its subdomains, ``*`` for any)."""
    host = host.strip().lower()
    name = host[1:host.index("]")] if host.startswith("[") and "]" in host else host.rsplit(":", 1)[0]
    for p in patterns:
        if p == "*" or p == name or (p.startswith("*.") and name.endswith(p[1:])):
            return True
    return False


#: answered whatever the Host (a load balancer's probes name the machine's address)
HOST_EXEMPT = ("/healthz", "/readyz")


class AllowedHosts:
    """ASGI middleware answering 400 to a request whose ``Host`` is not one of ``CHAKAMO_ALLOWED_HOSTS``
    (issue 16, finding 10d: a spoofed Host was echoed into the FHIR identifiers)."""

    def __init__(self, app, *, patterns: tuple[str, ...]) -> None:
        self.app, self.patterns = app, patterns

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] in ("http", "websocket") and scope.get("path") not in HOST_EXEMPT:
            host = next((v.decode("latin-1") for k, v in scope.get("headers", ()) if k == b"host"), "")
            if not host_allowed(host, self.patterns):
                from app.web.refusals import Refusal

                if scope["type"] == "websocket":
                    await send({"type": "websocket.close", "code": 1008})
                    return
                await Refusal(400, "request.host_not_allowed", host=host[:80]).response()(scope, receive, send)
                return
        await self.app(scope, receive, send)


def _own_scene(playback: str) -> bool:
    """Whether ``playback`` names a path under :data:`PLAYBACK_PREFIX` however the client decodes it: every
    level of percent-encoding undone (``%252e%252e`` is ``..`` to a browser's fetch) and the dots resolved."""
    decoded = playback
    for _ in range(5):
        once = unquote(decoded)
        if once == decoded:
            break
        decoded = once
    else:
        return False  # still encoded after five passes: nobody needs that for a file name
    if "\\" in decoded or not decoded.startswith("/"):
        return False
    return posixpath.normpath(decoded).startswith(PLAYBACK_PREFIX) and ".." not in decoded


class SecurityHeaders:
    """ASGI middleware adding the module docstring's headers; ``development`` drops HSTS (plain-http localhost)."""

    def __init__(self, app, *, development: bool) -> None:
        self.app, self.development = app, development

    def _headers(self, path: str) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
        """(headers set only when absent, headers always set) for an answer to ``path``."""
        defaults = [("X-Content-Type-Options", "nosniff"), ("Referrer-Policy", "no-referrer")]
        forced: list[tuple[str, str]] = []
        if path.startswith("/api/"):
            forced.append(("Cache-Control", "no-store"))
        if not self.development:
            forced.append(("Strict-Transport-Security", HSTS))
        if path.startswith("/viser"):
            forced.append(("Content-Security-Policy", VISER_CSP))
        elif path == "/" or path.startswith("/static"):
            forced += [("Content-Security-Policy", UI_CSP), ("X-Frame-Options", "SAMEORIGIN")]
        elif path == "/docs" or path.startswith("/docs-assets"):
            forced += [("Content-Security-Policy", DOCS_CSP), ("X-Frame-Options", "DENY")]
        return defaults, forced

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path = scope["path"]
        defaults, forced = self._headers(path)

        async def send_with_headers(message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                for name, value in defaults:
                    headers.setdefault(name, value)
                for name, value in forced:
                    headers[name] = value
            await send(message)

        if path.startswith("/viser"):
            pairs = parse_qsl(scope.get("query_string", b"").decode("latin-1"), keep_blank_values=True)
            playbacks = [v for k, v in pairs if k == "playbackPath"]
            if playbacks and not (len(playbacks) == 1 and _own_scene(playbacks[0])):
                refusal = JSONResponse({"detail": f"The 3D view plays only this server's scenes ({PLAYBACK_PREFIX}"
                                                  "…/scene.viser)."}, status_code=400)
                await refusal(scope, receive, send_with_headers)
                return
        await self.app(scope, receive, send_with_headers)


__all__ = ["AllowedHosts", "DOCS_CSP", "HOST_EXEMPT", "HSTS", "PLAYBACK_PREFIX", "REPORT_HTML_CSP", "SecurityHeaders", "UI_CSP", "VISER_CSP", "host_allowed"]
