"""JSON bodies no database can store, or no parser should recurse into, are refused at
the door, for every route.

JSON may escape any code point, so a body can carry a lone surrogate (`"\\ud800"`) or
NUL (`"\\u0000"`): Python's parser accepts both, pydantic's `str` does too, and then
SQLite's driver cannot encode the surrogate and PostgreSQL refuses NUL, which surfaced
as a 500 wherever a schema used a plain `str` (a trial plan's task names). Python's
parser also reads `NaN`, `Infinity` and `1e999` (an infinite float), which JSON does not
have and PostgreSQL's JSON columns refuse, and integers far beyond any database column.
Checking each schema's fields would leave the next field open; this middleware looks at
every JSON body once, before any route, and answers 422 naming the place, in the shape
of FastAPI's validation errors.

A JSON body must be UTF-8 (RFC 8259, section 8.1), and nothing else is read. Python's
parser, given bytes, guesses: a byte-order mark or NUL bytes among the first four make
it read UTF-16 or UTF-32, so `Infinity` written in UTF-16 once passed this door, which
read the bytes as UTF-8, and was stored. A body that is not strict UTF-8 (which also
refuses encoded surrogate halves), that starts with a byte-order mark, or that holds a
NUL byte (never valid in JSON text, and the parser's only cue for UTF-16/32 in a body
that is otherwise UTF-8) is refused before anything parses it. What passes is read as
UTF-8 by the parser too, so this door and the parser cannot see different text.

The body is measured before anything parses it: nesting deeper than `MAX_DEPTH` is
refused from the bytes alone (50,000 brackets once made the parser's recursion escape as
a 500), and the size is bounded by the body limit this middleware sits inside. Only a
body that may hold a problem is parsed here, and the parsed document is walked with a
loop, not recursion.
"""

from __future__ import annotations

import codecs
import json
import math
import re
from typing import Any

import numpy as np
from starlette.datastructures import Headers
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from backend.schemas.fields import _storable

#: Deepest nesting of arrays and objects a body may have; the API's deepest body (an
#: instrument definition) uses four levels.
MAX_DEPTH = 32
#: Integers must fit the databases' 64-bit integer columns: -2**63 <= n < 2**63.
INT_LIMIT = 2**63

#: A JSON escape of NUL or of a surrogate half: only a body holding one needs parsing
#: (paired halves decode to one character and pass).
_SUSPECT = re.compile(rb"\\u(?:0000|[dD][89a-fA-F][0-9a-fA-F]{2})")
#: A complete JSON string (possessive, so an unterminated one cannot backtrack).
_STRING = re.compile(rb'"(?:[^"\\]++|\\.)*+"', re.S)
#: Outside strings: a literal JSON does not have, an exponent of three digits or more,
#: or an integer of 19 digits or more; only these bodies need their numbers checked.
_ODD_NUMBER = re.compile(rb"NaN|Infinity|[eE][+-]?[0-9]{3,}|[0-9]{19,}")
#: Opening brackets to +1, closing ones to -1 (as signed bytes), everything else gone.
_STEP = bytes.maketrans(b"[{]}", b"\x01\x01\xff\xff")
_NOT_BRACKET = bytes(b for b in range(256) if b not in b"[]{}")


def _is_json(headers: Headers) -> bool:
    """The content types FastAPI parses as JSON (none given counts as JSON)."""
    ctype = headers.get("content-type", "").split(";", 1)[0].strip().lower()
    return not ctype or ctype == "application/json" or (
        ctype.startswith("application/") and ctype.endswith("+json"))


def _printable(key: Any) -> str | int:
    if isinstance(key, int):
        return key
    return str(key).encode("utf-8", "backslashreplace").decode("utf-8")


def nesting_depth(outside_strings: bytes) -> int:
    """The deepest nesting of brackets in JSON text whose strings are removed (counted
    on the bytes, vectorised: a megabyte of brackets takes milliseconds)."""
    steps = outside_strings.translate(None, _NOT_BRACKET).translate(_STEP)
    levels = np.cumsum(np.frombuffer(steps, dtype=np.int8), dtype=np.int64)
    return int(levels.max()) if levels.size else 0


class _Refused:
    """A number the parser met that no database stores (its text kept for the message)."""

    def __init__(self, text: str, problem: str) -> None:
        self.text, self.problem = text, problem


def _constant(name: str) -> _Refused:
    return _Refused(name, f"{name} is not a JSON number; numbers must be finite")


def _float(text: str) -> float | _Refused:
    value = float(text)
    if not math.isfinite(value):
        return _Refused(text, f"{text[:40]} is beyond the largest float; numbers must be "
                        "finite")
    return value


def _int(text: str) -> int | _Refused:
    if len(text.lstrip("-")) > 19 or not -INT_LIMIT <= int(text) < INT_LIMIT:
        return _Refused(text, f"{text[:40]}{'...' if len(text) > 40 else ''} is an integer "
                        "beyond 64 bits")
    return int(text)


def encoding_problem(body: bytes) -> str | None:
    """Why a body is not the UTF-8 text the parser is guaranteed to read as UTF-8 (None
    if it is). The parser decodes anything without a BOM or an early NUL as UTF-8."""
    if body.startswith(codecs.BOM_UTF8):
        return "JSON bodies must be UTF-8 without a byte-order mark (RFC 8259); this one " \
               "starts with one"
    if body[:4].startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)) or b"\x00" in body:
        return "JSON bodies must be UTF-8 (RFC 8259); this one holds NUL bytes or a " \
               "byte-order mark, as UTF-16 or UTF-32 text does"
    try:
        body.decode("utf-8", "strict")
    except UnicodeDecodeError as exc:
        return f"JSON bodies must be UTF-8 (RFC 8259); byte {exc.start} is not valid UTF-8"
    return None


def problems(body: bytes) -> list[dict[str, Any]]:
    """What is wrong with a JSON body, as FastAPI validation errors (empty: nothing, or
    not JSON at all, which the route's own parsing answers)."""
    bad_encoding = encoding_problem(body)
    if bad_encoding is not None:
        return [{"loc": ["body"], "type": "not_utf8", "msg": bad_encoding}]
    outside = _STRING.sub(b"", body)
    depth = nesting_depth(outside)
    if depth > MAX_DEPTH:
        return [{"loc": ["body"], "type": "too_deep",
                 "msg": f"arrays and objects nested {depth} deep; at most {MAX_DEPTH} "
                        "levels are accepted"}]
    if not _SUSPECT.search(body) and not _ODD_NUMBER.search(outside):
        return []
    try:
        doc = json.loads(body, parse_constant=_constant, parse_float=_float,
                         parse_int=_int)
    except (ValueError, RecursionError):
        return []  # not JSON: the route's own parsing answers that
    return [{"loc": ["body", *path], "msg": msg, "type": "value_error"}
            for path, msg in _walk(doc)]


def _walk(doc: Any) -> list[tuple[tuple[str | int, ...], str]]:
    """Each string (key or value) that cannot be stored and each refused number of a
    parsed document, as (path, problem), in document order; a loop, not recursion."""
    found: list[tuple[tuple[str | int, ...], str]] = []
    stack: list[tuple[tuple[str | int, ...], Any]] = [((), doc)]
    while stack:
        path, node = stack.pop()
        if isinstance(node, str):
            try:
                _storable(node)
            except ValueError as exc:
                found.append((path, str(exc)))
        elif isinstance(node, _Refused):
            found.append((path, node.problem))
        elif isinstance(node, dict):
            children: list[tuple[tuple[str | int, ...], Any]] = []
            for k, v in node.items():
                here = (*path, _printable(k))
                children.extend([(here, k), (here, v)])
            stack.extend(reversed(children))
        elif isinstance(node, list):
            stack.extend(reversed([((*path, i), v) for i, v in enumerate(node)]))
    return found


class StorableJsonText:
    """ASGI middleware: a JSON request body that is not UTF-8, nested too deep, or with a
    lone surrogate or NUL in any string, or a number no database stores (NaN,
    infinities, integers beyond 64 bits), is answered with 422 before the route runs;
    every other request passes unchanged. Install it inside the body-size limit, so the
    body it reads is bounded."""

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
        if body:
            found = problems(body)
            if found:
                await JSONResponse(status_code=422, content={"detail": found})(
                    scope, receive, send)
                return

        replay = [{"type": "http.request", "body": body, "more_body": False}] \
            if chunks else list(first)

        async def receive_again() -> Message:
            if replay:
                return replay.pop(0)
            return await receive()

        await self.app(scope, receive_again, send)
