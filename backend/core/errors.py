"""The refusals a service can give, without knowing about HTTP.

Services (backend/study, backend/analysis, backend/live) raise these; the API installs
one handler per class (backend/api/errors.py) that answers in the same shapes the routes'
own checks use: 404 and 409 with a sentence naming the entity or field, 422 with
FastAPI's list of `loc`/`msg`/`type`. So a service is usable from the CLI and the tests
as well, and a route stays "parse, authorise, call".
"""

from __future__ import annotations


class ServiceError(Exception):
    """Base of the refusals below; never raised itself."""


class NotFoundError(ServiceError):
    """An id that does not exist (404)."""

    def __init__(self, entity: str, key: object) -> None:
        super().__init__(f"{entity} {key} does not exist")
        self.entity, self.key = entity, key


class ConflictError(ServiceError):
    """A duplicate, or a state that forbids the change (409): `field: problem`."""

    def __init__(self, field: str, problem: str) -> None:
        super().__init__(f"{field}: {problem}")
        self.field, self.problem = field, problem


class InvalidError(ServiceError):
    """Input that passed the schema but not the domain rules (422), one or more
    problems, each at a location such as `["body", "rate_hz"]`."""

    def __init__(self, problems: list[tuple[list[str | int], str]]) -> None:
        super().__init__("; ".join(f"{'.'.join(map(str, loc))}: {msg}"
                                   for loc, msg in problems))
        self.problems = problems

    @classmethod
    def at(cls, loc: list[str | int], problem: str) -> InvalidError:
        """One problem at one location."""
        return cls([(loc, problem)])
