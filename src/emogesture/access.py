"""Who may use emogesture's servers (``emogesture live``, ``emogesture app``): the token rule and the origin rule.

The token rule, as Jupyter's: a server bound to this machine's loopback address (127.0.0.1, ::1, localhost)
takes anyone on this machine with no token; bound to any other address it needs one, given (``--token``) or
made at start (:func:`new_token`) and printed with the page's URL. A token given for a loopback server is
enforced too. A client gives it as ``?token=...`` on the URL (browsers cannot set headers on a WebSocket); a
browser that opens the page with it also gets it as a cookie, so that the page's own requests (its script,
its files) pass without it. A wrong or missing token is an HTTP 403.

The origin rule: a browser's WebSocket whose ``Origin`` names another site than the server's own page (another
host or port than the ``Host`` it asked for, the port left out being its scheme's: 80 for http, 443 for https)
is refused, whatever the address, so that no other site's page can drive the server from a visitor's browser;
clients that send no ``Origin`` (the command-line client, a game engine) are held to the token rule alone.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
import socket
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qs, urlencode, urlsplit, urlunsplit

from emogesture.errors import EmogestureError

LOOPBACK_NAMES = frozenset({"localhost", "localhost.localdomain", "ip6-localhost"})
DEFAULT_PORTS = {"http": 80, "https": 443}
FORBIDDEN_TEXT = "403: this server needs its token: open the URL it printed at start (...?token=...)\n"
FOREIGN_ORIGIN_TEXT = "403: a page of another site may not open this server's stream\n"


def is_loopback(host: str) -> bool:
    """Whether a server bound to ``host`` is reachable from this machine only."""
    name = host.strip().strip("[]").lower()
    if name in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False  # a host name, "" or "0.0.0.0"-like: other machines may reach it


def needs_token(host: str, token: str | None) -> bool:
    """Whether a server on ``host`` checks a token: always beyond loopback, on loopback when one is given."""
    return token is not None or not is_loopback(host)


def new_token() -> str:
    """A fresh random token (URL-safe, 32 bytes of entropy)."""
    return secrets.token_urlsafe(32)


def _check_given(token: str | None) -> None:
    if token is not None and not token.strip():
        raise EmogestureError("an empty token: give a word, or none for one made at start")


def server_token(host: str, token: str | None) -> str | None:
    """The token a server on ``host`` enforces: ``token`` when given, a new one when ``host`` is beyond
    loopback, else None (no token)."""
    _check_given(token)
    if needs_token(host, token):
        return token if token is not None else new_token()
    return None


def check_served(host: str, token: str | None) -> None:
    """Refuse to serve beyond loopback without a token (library callers; the command line makes one)."""
    _check_given(token)
    if needs_token(host, token) and token is None:
        raise EmogestureError(f"serving on {host or 'every address'} reaches other machines: give a token "
                              "(token=..., or --token), or serve on 127.0.0.1")


def url_host(host: str) -> str:
    """A server's bind address as a URL to it names the host: this machine's name for every address ("",
    0.0.0.0, ::), an IPv6 address in brackets."""
    if host in ("", "0.0.0.0", "::"):
        return socket.gethostname()
    return f"[{host}]" if ":" in host and not host.startswith("[") else host


def with_token(url: str, token: str | None) -> str:
    """``url`` with ``?token=`` set to ``token`` (unchanged when None)."""
    if token is None:
        return url
    parts = urlsplit(url)
    query = {k: v for k, v in parse_qs(parts.query).items() if k != "token"}
    query["token"] = [token]
    return urlunsplit(parts._replace(query=urlencode(query, doseq=True)))


def without_token(url: str) -> str:
    """``url`` with its token hidden, for messages and logs."""
    parts = urlsplit(url)
    if "token" not in parse_qs(parts.query):
        return url
    query = {k: v for k, v in parse_qs(parts.query).items() if k != "token"} | {"token": ["..."]}
    return urlunsplit(parts._replace(query=urlencode(query, doseq=True, safe=".")))


def same_origin(origin: str | None, host: str | None) -> bool:
    """Whether a browser's ``Origin`` header names the site of the ``Host`` it asked for (its host and port, the
    port by the origin's scheme when left out); no ``Origin`` (not a browser) passes."""
    if origin is None:
        return True
    site = urlsplit(origin.strip())
    if site.scheme not in ("http", "https") or not site.hostname or host is None:
        return False  # "null" (a local file, a sandbox) or something else: not the server's page
    asked = urlsplit(f"{site.scheme}://{host.strip()}")
    try:
        ports = (site.port or DEFAULT_PORTS[site.scheme], asked.port or DEFAULT_PORTS[site.scheme])
    except ValueError:
        return False  # a port that is not a number
    return site.hostname == asked.hostname and ports[0] == ports[1]


@dataclass(frozen=True)
class TokenCheck:
    """One server's token rule: ``token`` None lets everyone in; ``port`` names the server's cookie (cookies are
    shared by every port of a host)."""

    token: str | None
    port: int

    @property
    def cookie(self) -> str:
        """The name of the server's cookie."""
        return f"emogesture-token-{self.port}"

    @property
    def _cookie_value(self) -> str:
        """What the cookie holds: a keyed digest of the token (any characters of a given token fit a cookie,
        and the token itself is not kept in the browser)."""
        return hmac.new((self.token or "").encode(), b"emogesture cookie", "sha256").hexdigest()

    @staticmethod
    def _matches(given: str | None, expected: str | None) -> bool:
        return given is not None and expected is not None and hmac.compare_digest(given.encode(), expected.encode())

    def in_query(self, query: str) -> bool:
        """Whether the URL's query (``token=...``) holds the token."""
        return self._matches(parse_qs(query).get("token", [None])[-1], self.token)

    def in_cookie(self, cookie_header: str | None) -> bool:
        """Whether the ``Cookie`` header holds the token."""
        if not cookie_header:
            return False
        try:
            morsel = SimpleCookie(cookie_header).get(self.cookie)
        except CookieError:
            return False
        return morsel is not None and self._matches(morsel.value, self._cookie_value)

    def allows(self, query: str, cookie_header: str | None) -> bool:
        """Whether a request with this URL query and ``Cookie`` header may go on."""
        return self.token is None or self.in_query(query) or self.in_cookie(cookie_header)

    def set_cookie(self, query: str) -> str | None:
        """The ``Set-Cookie`` value for a response to a request whose query holds the token (None otherwise):
        the page's own requests then pass without it."""
        if self.token is None or not self.in_query(query):
            return None
        return f"{self.cookie}={self._cookie_value}; Path=/; HttpOnly; SameSite=Strict"
