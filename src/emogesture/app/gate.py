"""The web page's token rule (:mod:`emogesture.access`) as ASGI middleware in front of Gradio's app."""

from __future__ import annotations

from collections.abc import Awaitable, Callable

from emogesture.access import FORBIDDEN_TEXT, TokenCheck

Scope = dict
Receive = Callable[[], Awaitable[dict]]
Send = Callable[[dict], Awaitable[None]]


class TokenGate:
    """ASGI middleware: a request or WebSocket that carries the token (``?token=...``, or the cookie set on the
    response to the first such request, which the page's own requests then carry) goes on to ``app``; any other
    gets HTTP 403."""

    def __init__(self, app: Callable[[Scope, Receive, Send], Awaitable[None]], token: str, port: int) -> None:
        self.app = app
        self.check = TokenCheck(token, port)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)  # the server's start and stop
            return
        query = scope.get("query_string", b"").decode("latin-1")
        cookies = "; ".join(v.decode("latin-1") for k, v in scope.get("headers", []) if k.lower() == b"cookie")
        if not self.check.allows(query, cookies or None):
            await _refuse(scope, send)
            return
        cookie = self.check.set_cookie(query) if scope["type"] == "http" else None
        if cookie is None:
            await self.app(scope, receive, send)
            return

        async def send_with_cookie(message: dict) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []),
                                                  (b"set-cookie", cookie.encode("latin-1"))]}
            await send(message)

        await self.app(scope, receive, send_with_cookie)


async def _refuse(scope: Scope, send: Send) -> None:
    """HTTP 403 (a WebSocket closed before it is accepted is answered 403 by the server)."""
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008})
        return
    body = FORBIDDEN_TEXT.encode()
    await send({"type": "http.response.start", "status": 403,
                "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})
