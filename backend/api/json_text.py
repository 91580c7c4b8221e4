"""JSON bodies whose text no database can store are refused at the door, for every route.

JSON may escape any code point, so a body can carry a lone surrogate (`"\\ud800"`) or
NUL (`"\\u0000"`): Python's parser accepts both, pydantic's `str` does too, and then
SQLite's driver cannot encode the surrogate and PostgreSQL refuses NUL, which surfaced
as a 500 wherever a schema used a plain `str` (a trial plan's task names). Checking
each schema's fields would leave the next plain `str` open; this middleware looks at
every JSON body once, before any route, and answers 422 naming the field, in the shape
of FastAPI's validation errors.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from typing import Any

from starlette.datastructures import Headers
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from backend.schemas.fields import _storable

#: A JSON escape of NUL or of a surrogate half: only a body holding one needs parsing
#: (paired halves decode to one character and pass).
_SUSPECT = re.compile(rb"\\u(?:0000|[dD][89a-fA-F][0-9a-fA-F]{2})")


def _is_json(headers: Headers) -> bool:
    """The content types FastAPI parses as JSON (none given counts as JSON)."""
    ctype = headers.get("content-type", "").split(";", 1)[0].strip().lower()
    return not ctype or ctype == "application/json" or (
        ctype.startswith("application/") and ctype.endswith("+json"))


def _printable(key: Any) -> str | int:
    if isinstance(key, int):
        return key
    return str(key).encode("utf-8", "backslashreplace").decode("utf-8")


def unstorable(doc: Any, path: tuple[str | int, ...] = ()
               ) -> Iterator[tuple[tuple[str | int, ...], str]]:
    """Each string (key or value) of a parsed JSON document that cannot be stored, as
    (path, problem)."""
    if isinstance(doc, str):
        try:
            _storable(doc)
        except ValueError as exc:
            yield path, str(exc)
    elif isinstance(doc, dict):
        for k, v in doc.items():
            here = (*path, _printable(k))
            yield from unstorable(k, here)
            yield from unstorable(v, here)
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from unstorable(v, (*path, i))


class StorableJsonText:
    """ASGI middleware: a JSON request body with a lone surrogate or NUL in any string
    is answered with 422 before the route runs; every other request passes unchanged.
    Install it inside the body-size limit, so the body it reads is bounded."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not _is_json(Headers(scope=scope)):
            await self.app(scope, receive, send)
            return
        chunks: list[bytes] = []
        first: list[Message] = []
        while True:
            message = await receive()
            first.append(message)
            if message["type"] != "http.request":
                break
            chunks.append(message.get("body", b""))
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        if body and _SUSPECT.search(body):
            problems = _problems(body)
            if problems:
                await JSONResponse(status_code=422, content={"detail": problems})(
                    scope, receive, send)
                return

        replay = [{"type": "http.request", "body": body, "more_body": False}] \
            if chunks else list(first)

        async def receive_again() -> Message:
            if replay:
                return replay.pop(0)
            return await receive()

        await self.app(scope, receive_again, send)


def _problems(body: bytes) -> list[dict[str, Any]]:
    try:
        doc = json.loads(body)
    except ValueError:
        return []  # not JSON: the route's own parsing answers that
    return [{"loc": ["body", *path], "msg": msg, "type": "value_error"}
            for path, msg in unstorable(doc)]
