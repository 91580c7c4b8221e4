"""Answers FastAPI gives before a route's own code runs, added to the OpenAPI schema so
that it documents every status a client can get.

A body that is not valid UTF-8 JSON is refused by FastAPI with 400 ("There was an
error parsing the body") for any operation that takes a body; routes cannot declare
that themselves, so it is added here, to every such operation (the lead's routes too).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from fastapi import APIRouter, FastAPI
from fastapi.routing import APIRoute

_MALFORMED_BODY: dict[str, Any] = {
    "description": "the body could not be parsed",
    "content": {"application/json": {"schema": {
        "type": "object", "properties": {"detail": {}}, "required": ["detail"]}}},
}


def document_framework_errors(app: FastAPI) -> None:
    """Make `app.openapi()` include the framework's own 400 for operations with a body."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        schema = build()
        for item in schema.get("paths", {}).values():
            for op in item.values():
                if isinstance(op, dict) and "requestBody" in op:
                    op.setdefault("responses", {}).setdefault("400", _MALFORMED_BODY)
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


def _noun_forms(word: str) -> set[str]:
    """A tag's noun in both numbers: `trials` -> {trials, trial}, `study` -> {study, studies}."""
    forms = {word}
    if word.endswith("ies"):
        forms.add(word[:-3] + "y")
    elif word.endswith("s"):
        forms.add(word[:-1])
    elif word.endswith("y"):
        forms.add(word[:-1] + "ies")
    else:
        forms.add(word + "s")
    return forms


def _camel(words: list[str]) -> str:
    return words[0] + "".join(w[:1].upper() + w[1:] for w in words[1:])


def operation_name(function: str, tag: str) -> str:
    """The name the console's client calls an operation by: `<tag>.<verb>`.

    The tag in camel case, then the route function's name in camel case without a
    trailing tag noun: `start_trial` under `trials` is `trials.start`,
    `list_trial_segments` stays `trials.listTrialSegments`, `health` under `health`
    stays `health.health`. Derived, not listed, so a new route is named without an edit
    here; renaming the function renames the call, which the pages' lint then reports.
    """
    tag_words = tag.lower().replace("-", " ").split()
    words = [w for w in function.lower().split("_") if w]
    if not tag_words or not words:
        raise ValueError(f"cannot name operation {function!r} under tag {tag!r}")
    if len(words) > 1 and words[-1] in _noun_forms(tag_words[-1]):
        words = words[:-1]
    return f"{_camel(tag_words)}.{_camel(words)}"


def api_routes(app: FastAPI, routers: Sequence[APIRouter]) -> list[APIRoute]:
    """The app's own API routes and those of `routers` (included without a prefix), as
    their routers hold them.

    Read from the routers rather than through the app's flattened route contexts: FastAPI
    builds a context (dependencies, models, validators) for every route of the app the
    first time anything walks them, about 0.3 s of CPU per app, which a request to one
    route does not need."""
    return [r for r in [*app.router.routes, *(r for rt in routers for r in rt.routes)]
            if isinstance(r, APIRoute)]


def name_operations(app: FastAPI, routers: Sequence[APIRouter]) -> dict[tuple[str, str], str]:
    """Give every operation of `app.openapi()` its `operation_name` as `operationId`.

    Named now, when the app is built, so that two routes with one name stop the start
    (naming both) rather than an `/openapi.json` request. `routers` are the routers
    included in `app` (without a prefix). Returns the names by (METHOD, path), as the
    schema will carry them.
    """
    names: dict[tuple[str, str], str] = {}
    owners: dict[str, str] = {}
    for route in api_routes(app, routers):
        if not route.include_in_schema:
            continue
        path = route.path_format
        if not route.tags:
            raise RuntimeError(f"{path}: a route in the schema needs a tag (its client "
                               "namespace)")
        name = operation_name(route.name, str(route.tags[0]))
        for method in sorted(route.methods or ()):
            key = (method, path)
            # One function may answer several methods (HEAD beside GET is not in the
            # schema); a second method of the same function gets the method added.
            op = name if len(route.methods or ()) == 1 else f"{name}{method.title()}"
            where = f"{method} {path}"
            if op in owners:
                raise RuntimeError(f"operation name {op!r} of {where} is taken by "
                                   f"{owners[op]}: rename one of the route functions")
            owners[op] = where
            names[key] = op
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        schema = build()
        for path, item in schema.get("paths", {}).items():
            for method, op in item.items():
                name = names.get((method.upper(), path))
                if isinstance(op, dict) and name is not None:
                    op["operationId"] = name
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]
    return names
