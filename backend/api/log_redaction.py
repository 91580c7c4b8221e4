"""Participant link tokens never reach a log in full.

A participant link's token is its only credential (`/forms/{token}`,
`/api/participant-forms/{token}`), and uvicorn's access log writes every request path:
anyone who can read the log could open a participant's forms (issue 23). A logging
filter shortens such a token to its first characters, enough to tell two links apart
while debugging, in uvicorn's access and error logs and in whatever passes the root
logger's handlers (the app's own logs).
"""

from __future__ import annotations

import logging
import re

#: Characters of a token kept in logs: 6 of its 43 (36 of its 256 random bits), enough
#: to tell links apart, far from enough to guess one.
KEPT = 6

_TOKEN_PATH = re.compile(r"(/(?:api/participant-forms|forms)/)([A-Za-z0-9_-]{"
                         + str(KEPT) + r"})[A-Za-z0-9_-]+")


def redact(text: str) -> str:
    """`text` with every participant link token cut to its first `KEPT` characters."""
    return _TOKEN_PATH.sub(r"\1\2…", text)


class RedactTokens(logging.Filter):
    """Rewrites a record's message and string arguments with `redact` (never drops)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.msg, str):
            record.msg = redact(record.msg)
        if isinstance(record.args, tuple):
            record.args = tuple(redact(a) if isinstance(a, str) else a for a in record.args)
        return True


_FILTER = RedactTokens()


def install() -> None:
    """Add the filter to uvicorn's loggers and to the root logger's handlers (again
    after a logging reconfiguration: adding it twice is a no-op)."""
    for name in ("uvicorn.access", "uvicorn.error"):
        logging.getLogger(name).addFilter(_FILTER)
    for handler in logging.getLogger().handlers:
        handler.addFilter(_FILTER)
