"""The console's API client: one ES module written from the OpenAPI schema.

The pages reach the server only through `frontend/static/api_client.js`: one namespace
per tag, one function per operation, named by `backend.api.openapi.operation_name`
(`api.trials.start(trialId, body)`), plus the live WebSocket's path and its message
types from their pydantic models. A page never spells `/api/...` itself, so a renamed
or removed route is a lint error in the page that calls it (frontend/lint/), not a 404
in front of a participant.

The module is written to a file and committed, not served per request like the
vocabulary: ESLint checks the pages' calls against it without a server, and
`tests/frontend/test_api_client.py` fails when it no longer matches the schema. After
changing a route, regenerate it:

    .venv/bin/python -m backend.api.js_client
"""

from __future__ import annotations

import json
import re
import sys
import textwrap
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from pydantic import BaseModel
from pydantic.json_schema import models_json_schema

from backend.core import resources
from backend.schemas.lab import LiveMarker
from backend.schemas.live import LiveEmg, LiveStatus, LiveTicks

#: Every message `/ws/live` sends, by its `type` (backend/live/stream.py sends the
#: ticks, backend/api/routes/live.py the status, backend/lab/hub.py the markers,
#: backend/emg/live_envelope.py the EMG envelopes).
LIVE_MESSAGES: tuple[type[BaseModel], ...] = (LiveTicks, LiveStatus, LiveMarker, LiveEmg)

#: The file the pages import, `/static/api_client.js`.
CLIENT_FILE = "api_client.js"

_METHODS = ("get", "post", "put", "patch", "delete")
_HEADER = """\
// ExoStudy's API client, written by backend/api/js_client.py from the server's OpenAPI
// schema and its live message models. Do not edit: after changing a route, regenerate
// it with `.venv/bin/python -m backend.api.js_client` (a test fails while it is stale).
//
// A call takes the path parameters in path order, then the body (if the operation has
// one), then an object of query parameters (if it has any):
//   api.trials.start(trialId, {})    api.results.modelEvaluation(studyId, { model_set_id })
// `.url(...)` builds the address alone (links, images), `.text(...)` reads a text answer.
import { operation, messageReader } from "./api.js";
"""


def _camel(name: str) -> str:
    words = [w for w in re.split(r"[^0-9A-Za-z]+", name) if w]
    return words[0].lower() + "".join(w[:1].upper() + w[1:].lower() for w in words[1:])


def _comment(text: str) -> str:
    """One line of prose, safe inside a block comment."""
    return " ".join(text.split()).replace("*/", "* /")


def js_type(schema: Any) -> str:
    """A JSON schema as a JSDoc type (`Array<MarkerOut>`, `(number|null)`, ...)."""
    if not isinstance(schema, dict) or not schema:
        return "*"
    if "$ref" in schema:
        return str(schema["$ref"]).rsplit("/", 1)[-1]
    if "const" in schema:
        return json.dumps(schema["const"])
    if "enum" in schema:
        return "(" + "|".join(json.dumps(v) for v in schema["enum"]) + ")"
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return "(" + "|".join(js_type(s) for s in schema[key]) + ")"
    kind = schema.get("type")
    if kind in ("integer", "number"):
        return "number"
    if kind in ("string", "boolean", "null"):
        return str(kind)
    if kind == "array":
        return f"Array<{js_type(schema.get('items'))}>"
    if kind == "object":
        extra = schema.get("additionalProperties")
        return f"Object<string, {js_type(extra)}>" if isinstance(extra, dict) else "object"
    return "*"


def _answer(op: dict[str, Any]) -> str:
    """The JSDoc type of an operation's success answer (JSON), or what it is instead."""
    for code, answer in sorted(op.get("responses", {}).items()):
        if not code.startswith("2"):
            continue
        if code == "204":
            return "null"
        content = answer.get("content", {})
        if "application/json" in content:
            return js_type(content["application/json"].get("schema"))
        if content:
            return "*"  # a file: use .url() or .text()
    return "*"


def _operation(path: str, method: str, op: dict[str, Any]) -> tuple[str, str, str]:
    """(namespace, name, JavaScript property) of one schema operation."""
    op_id = str(op.get("operationId", ""))
    if not re.fullmatch(r"[a-z][A-Za-z0-9]*\.[a-z][A-Za-z0-9]*", op_id):
        raise ValueError(f"{method.upper()} {path}: operationId {op_id!r} is not "
                         "<namespace>.<name> (backend/api/openapi.py names them)")
    namespace, name = op_id.split(".")
    parameters = op.get("parameters", [])
    in_path = {p["name"]: p for p in parameters if p.get("in") == "path"}
    ordered = re.findall(r"{([^}]+)}", path)
    if set(ordered) != set(in_path):
        raise ValueError(f"{method.upper()} {path}: path parameters {ordered} differ from "
                         f"the declared {sorted(in_path)}")
    in_query = {p["name"]: p for p in parameters if p.get("in") == "query"}
    query = list(in_query)
    body = op.get("requestBody")
    # The route's docstring, first paragraph (FastAPI's summary is the function name).
    about = (op.get("description") or "").split("\n\n")[0] or op.get("summary") or op_id
    doc = textwrap.wrap(f"{method.upper()} {path}: {_comment(about)}", 88)
    for p in ordered:
        doc.append(f"@param {{{js_type(in_path[p].get('schema'))}}} {_camel(p)}")
    if body is not None:
        schemas = [js_type(c.get("schema")) for c in body.get("content", {}).values()]
        optional = "" if body.get("required") else "="
        doc.append(f"@param {{{(schemas or ['*'])[0]}{optional}}} body")
    if query:
        fields = ", ".join(f"{q}?: {js_type(p.get('schema'))}" for q, p in in_query.items())
        doc.append(f"@param {{{{{fields}}}=}} query")
    doc.append(f"@returns {{Promise<{_answer(op)}>}}")
    options = {"params": ordered, "query": query, "body": body is not None}
    lines = ["  /**", *(f"   * {line}" for line in doc), "   */",
             f"  {name}: operation({json.dumps(op_id)}, {json.dumps(method.upper())}, "
             f"{json.dumps(path)}, {json.dumps(options, separators=(', ', ': '))}),"]
    return namespace, name, "\n".join(lines)


def _typedefs(schemas: dict[str, Any]) -> list[str]:
    out = []
    for name, schema in sorted(schemas.items()):
        lines = ["/**"]
        if schema.get("description"):
            lines.append(f" * {_comment(schema['description'])}")
        lines.append(f" * @typedef {{object}} {name}")
        for field, prop in schema.get("properties", {}).items():
            note = f" {_comment(prop['description'])}" if prop.get("description") else ""
            lines.append(f" * @property {{{js_type(prop)}}} {field}{note}")
        lines.append(" */")
        out.append("\n".join(lines))
    return out


def _live_section() -> str:
    """Typedefs of the live messages and their fields by `type`, from the models."""
    _, schema = models_json_schema([(m, "serialization") for m in LIVE_MESSAGES],
                                   ref_template="{model}")
    defs = schema.get("$defs", {})
    fields: dict[str, list[str]] = {}
    for model in LIVE_MESSAGES:
        kind = model.model_fields["type"].default
        if not isinstance(kind, str) or kind in fields:
            raise ValueError(f"{model.__name__}: `type` must be a literal of its own")
        # The server writes every field (pydantic dumps defaults too), so a page may
        # rely on each one being there.
        fields[kind] = list(model.model_fields)
    names = " | ".join(m.__name__ for m in LIVE_MESSAGES)
    body = "\n\n".join(_typedefs(defs))
    return (
        "\n// The live WebSocket: its path and its messages (backend/schemas/live.py and\n"
        "// backend/schemas/lab.py), as typedefs and as the fields each `type` carries.\n\n"
        f"{body}\n\n"
        f"/** @typedef {{{names}}} LiveMessage */\n\n"
        "/** The fields of each live message, by its `type`. */\n"
        f"export const LIVE_MESSAGES = Object.freeze({json.dumps(fields)});\n\n"
        "/** A live message from its JSON text, checked against LIVE_MESSAGES.\n"
        " * @type {(text: string) => LiveMessage} */\n"
        "export const readLiveMessage = messageReader(LIVE_MESSAGES);\n"
    )


def client_module(schema: dict[str, Any], sockets: dict[str, str]) -> str:
    """The client module for an OpenAPI schema and the app's WebSocket paths."""
    namespaces: dict[str, dict[str, str]] = {}
    for path, item in schema.get("paths", {}).items():
        for method in _METHODS:
            op = item.get(method)
            if op is None:
                continue
            namespace, name, prop = _operation(path, method, op)
            if name in namespaces.setdefault(namespace, {}):
                raise ValueError(f"{method.upper()} {path}: {namespace}.{name} is taken")
            namespaces[namespace][name] = prop
    parts = [_HEADER]
    for namespace in sorted(namespaces):
        ops = namespaces[namespace]
        parts.append(f"\nexport const {namespace} = Object.freeze({{\n"
                     + "\n".join(ops[n] for n in sorted(ops)) + "\n});\n")
    paths = json.dumps(dict(sorted(sockets.items())))
    parts.append("\n/** The WebSocket paths, by route name. */\n"
                 f"export const sockets = Object.freeze({paths});\n")
    parts.append(_live_section())
    return "".join(parts)


def app_sockets(app: FastAPI) -> dict[str, str]:
    """The app's WebSocket routes under `/ws/` (the viewer's relay serves viser's own
    page, not ours), by route name."""
    from fastapi.routing import APIWebSocketRoute, iter_route_contexts
    from starlette.routing import WebSocketRoute

    out = {}
    for context in iter_route_contexts(app.routes):
        route = context.original_route
        if isinstance(route, (APIWebSocketRoute, WebSocketRoute)):
            path = context.path_format or route.path_format
            if path.startswith("/ws/"):
                out[_camel(route.name)] = path
    return out


def app_client_module(app: FastAPI) -> str:
    """The client module of a built app, as it should be committed."""
    return client_module(app.openapi(), app_sockets(app))


def main(argv: list[str] | None = None) -> int:
    """Write the client module (default: frontend/static/api_client.js)."""
    from backend.core.config import Settings
    from backend.main import create_app

    args = sys.argv[1:] if argv is None else argv
    target = Path(args[0]) if args else resources.frontend_dir() / "static" / CLIENT_FILE
    text = app_client_module(create_app(Settings(start_worker=False)))
    old = target.read_text() if target.is_file() else None
    if old != text:
        target.write_text(text)
    print(f"{target}: {'unchanged' if old == text else 'written'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
