"""Answers FastAPI gives before a route's own code runs, added to the OpenAPI schema so
that it documents every status a client can get.

A body that is not valid UTF-8 JSON is refused by FastAPI with 400 ("There was an
error parsing the body") for any operation that takes a body; routes cannot declare
that themselves, so it is added here, to every such operation (the lead's routes too).
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI

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
