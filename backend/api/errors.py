"""Error answers that name the field and the problem, in FastAPI's own shapes.

404 and 409 carry a sentence in `detail` that starts with the field or entity; 422
from our own checks uses the same list-of-errors shape as FastAPI's request validation
(`loc`, `msg`, `type`), so clients handle one format.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any, NoReturn, TypeVar

from fastapi import FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from backend.core.errors import ConflictError, InvalidError, NotFoundError

T = TypeVar("T")


class ErrorMessage(BaseModel):
    """`detail` is a sentence naming the field or entity, or a list of field errors."""

    detail: str | list[dict[str, Any]] | dict[str, Any]


def not_found(entity: str, key: object) -> NoReturn:
    """404 for an unknown id."""
    raise HTTPException(404, f"{entity} {key} does not exist")


def conflict(field: str, problem: str) -> NoReturn:
    """409 for a duplicate or a state that forbids the change."""
    raise HTTPException(409, f"{field}: {problem}")


def invalid(loc: list[str | int], problem: str) -> NoReturn:
    """422 for input that passed the schema but not the domain rules."""
    raise HTTPException(422, [{"loc": loc, "msg": problem, "type": "value_error"}])


def invalid_many(problems: list[tuple[list[str | int], str]]) -> NoReturn:
    """422 listing every problem at once (a form with three bad answers names three)."""
    raise HTTPException(422, [{"loc": loc, "msg": msg, "type": "value_error"}
                              for loc, msg in problems])


#: Responses every experimenter route can give, for the OpenAPI schema.
AUTH_RESPONSES: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorMessage, "description": "not logged in"},
}
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorMessage, "description": "an id in the path does not exist"},
}
INVALID: dict[int | str, dict[str, Any]] = {
    422: {"model": ErrorMessage,
          "description": "a parameter or field is invalid; `loc` names it"},
}
MALFORMED: dict[int | str, dict[str, Any]] = {
    400: {"model": ErrorMessage, "description": "the body is not parseable JSON"},
}
BODY: dict[int | str, dict[str, Any]] = {**MALFORMED, **INVALID}
CONFLICT: dict[int | str, dict[str, Any]] = {
    409: {"model": ErrorMessage, "description": "duplicate, or not allowed in this state"},
}


def one_or_404(db: Session, model: type[T], key: int, entity: str) -> T:
    """The row with primary key `key`, or 404 naming the entity."""
    row = db.get(model, key)
    if row is None:
        not_found(entity, key)
    return row


def commit_or_conflict(db: Session, field: str, problem: str) -> None:
    """Commit; a unique constraint that a concurrent request won is a 409, not a 500
    (the checks before the write cannot see another transaction's row)."""
    try:
        db.commit()
    except IntegrityError as exc:
        db.rollback()
        conflict(field, problem)
        raise AssertionError("unreachable") from exc


def _json_safe(v: Any) -> bool:
    """True if `v` encodes as strict JSON (no NaN/Infinity, no lone surrogates)."""
    try:
        json.dumps(v, allow_nan=False, ensure_ascii=False).encode("utf-8")
    except (ValueError, TypeError, UnicodeEncodeError):
        return False
    return True


def safe_validation_errors(errors: Sequence[Any]) -> list[dict[str, Any]]:
    """FastAPI's validation errors, without the parts that cannot be JSON: the very
    input that was refused (NaN, a lone surrogate) must not turn the 422 into a 500."""
    out = []
    for e in errors:
        item = {k: e[k] for k in ("type", "loc", "msg") if k in e}
        item["msg"] = str(item.get("msg", "")).encode("utf-8", "replace").decode("utf-8")
        for k in ("input", "ctx"):
            if k in e and _json_safe(e[k]) and len(json.dumps(e[k])) <= 1000:
                item[k] = e[k]
        out.append(item)
    return out


async def _validation_handler(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    return JSONResponse(status_code=422,
                        content={"detail": safe_validation_errors(exc.errors())})


async def _service_handler(request: Request, exc: Exception) -> JSONResponse:
    """A service's refusal, in the shape the routes' own checks give."""
    if isinstance(exc, NotFoundError):
        return JSONResponse(status_code=404, content={"detail": str(exc)})
    if isinstance(exc, ConflictError):
        return JSONResponse(status_code=409, content={"detail": str(exc)})
    assert isinstance(exc, InvalidError)
    return JSONResponse(status_code=422, content={"detail": [
        {"loc": loc, "msg": msg, "type": "value_error"} for loc, msg in exc.problems]})


def install_handlers(app: FastAPI) -> None:
    """Answer every request validation error with a 422 that can always be encoded, and
    the services' refusals (backend/core/errors.py) with 404, 409 or 422."""
    app.add_exception_handler(RequestValidationError, _validation_handler)
    for cls in (NotFoundError, ConflictError, InvalidError):
        app.add_exception_handler(cls, _service_handler)
