"""Who may talk to the editor: every HTTP request and every websocket handshake (pages, static
files, ``/files/...``, socket.io polling and websockets) passes :class:`RequestGuard` first.

- **Host** must name the address the server listens on, with its port: on the loopback
  ``127.0.0.1``, ``localhost`` or ``[::1]``; with ``--host NAME`` also ``NAME``. A web page whose
  own name was made to resolve to 127.0.0.1 (DNS rebinding) sends its own name as Host and gets
  421 (Misdirected Request).
- **Origin**, when a browser sends one (every cross-origin request and every websocket
  handshake), must be the server's own ``http://host:port``; anything else (another site,
  ``null``) gets 403. Requests without Origin (a typed address, curl) pass on Host alone.
- **Token**, when the server has one (``--host`` other than the loopback): ``?token=`` once (then
  an HttpOnly, SameSite=Strict cookie) on every request, socket.io polling and websockets included.

A pure ASGI middleware, so websockets (which Starlette's ``@app.middleware("http")`` never sees)
are checked too. References: RFC 9110 §7.2 (Host), RFC 6454 (origins), RFC 6455 §10.2 (websocket
Origin), RFC 9110 §15.5.20 (421).
"""

from __future__ import annotations

import secrets
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qs, urlsplit

#: names of the loopback interface a browser may use for a server bound there
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")
#: binds that listen on every interface: any Host name then (the token guards them)
WILDCARD_BINDS = ("0.0.0.0", "::", "")
TOKEN_COOKIE = "humv_editor_token"


def split_host(value: str) -> tuple[str, int] | None:
    """``"name:port"`` / ``"[v6]:port"`` / ``"name"`` → (lower-case name without brackets, port);
    None when it is not a host (empty, bad port, stray characters). No port means 80 (http)."""
    value = value.strip()
    if not value or any(c in value for c in "/\\@ ?#\x00"):
        return None
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return None
        name, rest = value[1:end], value[end + 1 :]
        if rest and not rest.startswith(":"):
            return None
        port_text = rest[1:] if rest else ""
    else:
        if value.count(":") > 1:  # a bare IPv6 address is not a valid Host
            return None
        name, _, port_text = value.partition(":")
    if not name:
        return None
    if port_text == "":
        port = 80
    elif port_text.isdigit() and 0 < int(port_text) < 65536:
        port = int(port_text)
    else:
        return None
    return name.lower(), port


class RequestGuard:
    """ASGI middleware refusing requests and websocket handshakes whose Host, Origin or token
    is not the editor's own (see the module docstring).

    Parameters
    ----------
    app
        The wrapped ASGI application.
    host : str
        The interface the server was bound to (``--host``).
    port : int
        The port it listens on.
    token : str or None
        The secret every request must carry (None: no token, loopback only).
    """

    def __init__(self, app, host: str, port: int, token: str | None = None):
        self.app = app
        self.port = int(port)
        bound = host.strip("[]").lower()
        self.any_name = bound in WILDCARD_BINDS
        self.names = set(LOOPBACK_NAMES) | {bound}
        self.token = token

    def refusal(self, scope) -> tuple[int, str] | None:
        """(status, reason) when the request must be refused, else None."""
        hosts = [v for k, v in scope.get("headers", ()) if k.lower() == b"host"]
        if len(hosts) != 1:
            return 421, "humv-usd edit: exactly one Host header expected"
        host = split_host(hosts[0].decode("latin-1"))
        if host is None or host[1] != self.port or not (self.any_name or host[0] in self.names):
            return 421, (
                f"humv-usd edit: Host {hosts[0].decode('latin-1')!r} is not this server "
                f"(expected {' or '.join(sorted(self.names))} with port {self.port})"
            )
        origins = [v for k, v in scope.get("headers", ()) if k.lower() == b"origin"]
        if len(origins) > 1:
            return 403, "humv-usd edit: more than one Origin header"
        if origins:
            origin = origins[0].decode("latin-1")
            try:  # urlsplit raises on a broken IPv6 literal ("http://[::1": a 500 before, fuzzing)
                parts = urlsplit(origin)
                same = (
                    parts.scheme == "http" and not parts.path.strip("/") and split_host(parts.netloc) == host
                )
            except ValueError:
                same = False
            if not same:
                return 403, f"humv-usd edit: cross-origin request from {origin!r} refused"
        # bytes: compare_digest refuses str with non-ASCII characters (?token=%80 was a 500, fuzzing)
        given = (self._given_token(scope) or "").encode("utf-8", "surrogateescape")
        if self.token and not secrets.compare_digest(given, self.token.encode("utf-8")):
            return 403, "humv-usd edit: open the address with ?token=... printed at start"
        return None

    @staticmethod
    def _query_token(scope) -> str | None:
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        values = query.get("token")
        return values[-1] if values else None

    def _given_token(self, scope) -> str | None:
        given = self._query_token(scope)
        if given:
            return given
        for key, value in scope.get("headers", ()):
            if key.lower() == b"cookie":
                try:
                    cookie = SimpleCookie(value.decode("latin-1"))
                except CookieError:
                    continue
                if TOKEN_COOKIE in cookie:
                    return cookie[TOKEN_COOKIE].value
        return None

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        refused = self.refusal(scope)
        if refused is not None:
            status, reason = refused
            if scope["type"] == "websocket":
                # closing before accepting: the server answers the handshake with 403
                await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
                return
            body = (reason + "\n").encode("utf-8")
            await send(
                {
                    "type": "http.response.start",
                    "status": status,
                    "headers": [
                        (b"content-type", b"text/plain; charset=utf-8"),
                        (b"content-length", str(len(body)).encode()),
                        (b"cache-control", b"no-store"),
                    ],
                }
            )
            await send({"type": "http.response.body", "body": body})
            return
        if not (self.token and scope["type"] == "http" and self._query_token(scope)):
            await self.app(scope, receive, send)
            return
        cookie = f"{TOKEN_COOKIE}={self.token}; HttpOnly; SameSite=Strict; Path=/".encode()

        async def send_with_cookie(message):
            if message["type"] == "http.response.start":
                message = dict(message, headers=[*message.get("headers", ()), (b"set-cookie", cookie)])
            await send(message)

        await self.app(scope, receive, send_with_cookie)
