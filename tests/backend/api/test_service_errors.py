"""A service's refusal reaches the client in the shapes the routes' own checks give:
404/409 with a sentence naming the entity or field, 422 as a list of `loc`/`msg`/`type`."""

from __future__ import annotations

from fastapi import FastAPI
from fastapi.testclient import TestClient

from backend.api.errors import conflict, install_handlers, invalid, not_found
from backend.core.errors import ConflictError, InvalidError, NotFoundError


def _app() -> FastAPI:
    app = FastAPI()
    install_handlers(app)

    @app.get("/service/{kind}")
    def service(kind: str) -> None:
        if kind == "404":
            raise NotFoundError("trial", 7)
        if kind == "409":
            raise ConflictError("status", "trial 7 is running")
        raise InvalidError([(["body", "rate_hz"], "too fast"), (["body", 0, "end"], "late")])

    @app.get("/route/{kind}")
    def route(kind: str) -> None:
        if kind == "404":
            not_found("trial", 7)
        if kind == "409":
            conflict("status", "trial 7 is running")
        invalid(["body", "rate_hz"], "too fast")

    return app


def test_service_refusals_answer_like_the_routes() -> None:
    client = TestClient(_app())
    for kind in ("404", "409", "422"):
        from_service = client.get(f"/service/{kind}")
        from_route = client.get(f"/route/{kind}")
        assert from_service.status_code == from_route.status_code == int(kind)
        if kind != "422":
            assert from_service.json() == from_route.json()
    assert client.get("/service/404").json() == {"detail": "trial 7 does not exist"}
    assert client.get("/service/409").json() == {"detail": "status: trial 7 is running"}
    assert client.get("/service/422").json() == {"detail": [
        {"loc": ["body", "rate_hz"], "msg": "too fast", "type": "value_error"},
        {"loc": ["body", 0, "end"], "msg": "late", "type": "value_error"}]}
    assert client.get("/route/422").json()["detail"] == [
        {"loc": ["body", "rate_hz"], "msg": "too fast", "type": "value_error"}]
