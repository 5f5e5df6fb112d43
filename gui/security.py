"""Request safety for the web application: CSRF tokens, trusted hosts, security headers (docs/operator.md).

Trusted hosts: bound to the loopback interface, the app answers only requests whose ``Host`` header names a
loopback host (``127.0.0.1``, ``localhost``, ``[::1]``, any port), so a web page elsewhere cannot reach it
through DNS rebinding. Werkzeug's own check cannot match an IPv6 literal (it cuts the trusted name at its
first colon), so the check is here.

CSRF: every browser session gets a random token kept in Flask's signed session cookie (signed with
``itsdangerous`` under the app's secret key, ``SameSite=Strict``); every state-changing request (any method
but GET, HEAD, OPTIONS) must send the same token as the form field ``csrf_token`` or the header
``X-CSRF-Token``, compared in constant time. A missing or wrong token is answered with 400 before the view
runs, so nothing changes.
"""

from __future__ import annotations

import hmac
import secrets
from collections.abc import Callable, Iterable

from flask import Flask, Response, abort, request, session

CSRF_FIELD = "csrf_token"
CSRF_HEADER = "X-CSRF-Token"
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

CONTENT_SECURITY_POLICY = ("default-src 'self'; img-src 'self' data: blob:; style-src 'self'; "
                           "script-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'; "
                           "form-action 'self'")
"""No inline scripts or styles, nothing from other origins, never inside a frame."""


def csrf_token() -> str:
    """This browser session's CSRF token (created on first use)."""
    token = session.get(CSRF_FIELD)
    if not token:
        token = session[CSRF_FIELD] = secrets.token_urlsafe(32)
    return token


def check_csrf() -> None:
    """Refuse (400) a state-changing request whose token is missing or differs from the session's."""
    if request.method in SAFE_METHODS:
        return
    expected = session.get(CSRF_FIELD)
    sent = request.headers.get(CSRF_HEADER) or request.form.get(CSRF_FIELD)
    if not expected or not sent or not hmac.compare_digest(str(sent), str(expected)):
        abort(400, description="the form's security token is missing or out of date; reload the page and "
                               "submit it again (nothing was changed)")


def host_name(host: str) -> str:
    """The name of a ``Host`` header without its port, IPv6 brackets removed: ``[::1]:8080`` -> ``::1``."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1:host.index("]")] if "]" in host else host
    return host.rpartition(":")[0] if ":" in host else host


def trusted_host_check(trusted: Iterable[str]) -> Callable[[], None]:
    """A before-request hook refusing (400, before anything runs) a ``Host`` header not naming ``trusted``."""
    names = frozenset(host_name(f"[{name}]" if ":" in name else name) for name in trusted)

    def check() -> None:
        if host_name(request.host) not in names:
            abort(400, description=f"this server answers only to {', '.join(sorted(names))}")

    return check


def add_security_headers(response: Response) -> Response:
    """Content security policy, no MIME sniffing, no framing, no caching of pages with form tokens."""
    response.headers.setdefault("Content-Security-Policy", CONTENT_SECURITY_POLICY)
    response.headers.setdefault("X-Content-Type-Options", "nosniff")
    response.headers.setdefault("X-Frame-Options", "DENY")
    response.headers.setdefault("Referrer-Policy", "same-origin")
    if response.mimetype in ("text/html", "application/json"):
        response.headers.setdefault("Cache-Control", "no-store")
    return response


def install(app: Flask, trusted_hosts: Iterable[str] | None = None) -> None:
    """Wire the trusted-host check (None: any host), the CSRF check, the token for templates and the headers
    into ``app``."""
    app.config.update(SESSION_COOKIE_HTTPONLY=True, SESSION_COOKIE_SAMESITE="Strict")
    if trusted_hosts:
        app.before_request(trusted_host_check(trusted_hosts))
    app.before_request(check_csrf)
    app.after_request(add_security_headers)
    app.jinja_env.globals["csrf_token"] = csrf_token
