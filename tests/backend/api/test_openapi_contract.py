"""Every route's answer is described by the OpenAPI schema: JSON answers by a response
model, files and pages by their media type. A route added without one fails here."""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.responses import Response

from backend.core.config import Settings
from backend.main import create_app


def _undescribed_json(schema: Any, components: dict[str, Any]) -> bool:
    """True if a JSON schema says nothing about the answer's shape (`{}`, an object
    with any keys, or a list of such)."""
    if not isinstance(schema, dict) or not schema:
        return True
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[-1]
        return name not in components
    if "anyOf" in schema or "oneOf" in schema:
        return any(_undescribed_json(s, components)
                   for s in schema.get("anyOf", schema.get("oneOf", [])))
    if schema.get("type") == "array":
        return _undescribed_json(schema.get("items"), components)
    if schema.get("type") == "object":
        return "properties" not in schema and not isinstance(
            schema.get("additionalProperties"), dict)
    return "type" not in schema


def undescribed(openapi: dict[str, Any]) -> list[str]:
    """The operations whose success answer the schema does not describe."""
    components = openapi.get("components", {}).get("schemas", {})
    bad = []
    for path, item in openapi["paths"].items():
        for method, op in item.items():
            success = {code: r for code, r in op.get("responses", {}).items()
                       if code.startswith("2")}
            if not success:
                bad.append(f"{method.upper()} {path}: no success answer")
                continue
            for code, answer in success.items():
                content = answer.get("content")
                if code == "204":
                    continue
                if not content:
                    bad.append(f"{method.upper()} {path} {code}: no media type")
                    continue
                for media, body in content.items():
                    if media == "application/json" and _undescribed_json(
                            body.get("schema"), components):
                        bad.append(f"{method.upper()} {path} {code}: JSON without a "
                                   "response model")
    return bad


def test_every_route_describes_its_answer(settings: Settings) -> None:
    app = create_app(settings)
    openapi = app.openapi()
    assert len(openapi["paths"]) > 50  # the whole API, not an empty app
    assert undescribed(openapi) == []


def test_a_route_without_a_response_model_is_caught() -> None:
    # The check above must be able to fail: an untyped JSON answer, a bare object and
    # a file answer without its media type are each reported.
    app = FastAPI()

    @app.get("/untyped")
    def untyped() -> Any:
        return {"a": 1}

    @app.get("/any-object", response_model=dict[str, Any])
    def any_object() -> dict[str, Any]:
        return {}

    @app.get("/file", response_class=Response)
    def file() -> Response:
        return Response(b"x", media_type="application/octet-stream")

    @app.get("/typed", response_model=list[int])
    def typed() -> list[int]:
        return [1]

    found = undescribed(app.openapi())
    assert [f.split(":")[0] for f in found] == ["GET /untyped 200", "GET /any-object 200",
                                                "GET /file 200"]
