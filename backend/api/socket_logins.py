"""WebSockets end with the login they were opened with.

A WebSocket is authenticated once, at its handshake; without more, it would keep
streaming after the browser logged out, after "log out everywhere" or after an
administrator disabled the account (issue 23: 742 messages in 15 s after logout).
Each socket therefore runs a watcher beside its work. The watcher re-reads its login
(`AuthToken` row and account) when the API revokes logins of that account (logout,
revoke-all, password change, disabling: `logins_changed`), and every
`RECHECK_S` seconds for what no request announces (a login's expiry, `exostudy user
disable` run from another process). When the login is no longer valid, the socket is
closed with 1008 (policy violation) and a reason.
"""

from __future__ import annotations

import asyncio
import logging
from datetime import UTC, datetime

from sqlalchemy.orm import Session, sessionmaker
from starlette.websockets import WebSocket, WebSocketState

from backend.db.models import AuthToken, User

log = logging.getLogger(__name__)

#: Seconds between re-reads of a socket's login when nothing announced a change. An
#: assumption: a login that expires or is disabled from the command line stops
#: streaming within this; revocations through the API close sockets at once. One
#: indexed read per open socket per period costs nothing measurable.
RECHECK_S = 5.0


def _aware(t: datetime) -> datetime:
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


def login_problem(sessions: sessionmaker[Session], token_id: int) -> str | None:
    """Why the login `token_id` no longer holds (logged out, expired, account
    disabled), or None while it is valid."""
    with sessions() as db:
        row = db.get(AuthToken, token_id)
        user = db.get(User, row.user_id) if row is not None else None
        # The account first: disabling it also revokes its logins.
        if user is None or not user.active:
            return "account disabled"
        if row is None or row.revoked_at is not None:
            return "logged out"
        if _aware(row.expires_at) <= datetime.now(UTC):
            return "login expired"
    return None


class SocketLogins:
    """The open sockets' watchers by account, so a revocation wakes them at once."""

    def __init__(self) -> None:
        # account -> the watchers of its open sockets, each with the loop it waits on.
        self._watchers: dict[int, set[tuple[asyncio.AbstractEventLoop, asyncio.Event]]] = {}

    @property
    def open_count(self) -> int:
        """Sockets being watched (tests and health)."""
        return sum(len(s) for s in list(self._watchers.values()))

    def logins_changed(self, user_id: int) -> None:
        """Some login of `user_id` was revoked or the account changed: its sockets
        re-read their login now. Callable from any thread (sync routes run in one)."""
        for loop, event in list(self._watchers.get(user_id, ())):
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:
                pass  # that loop closed: its socket is gone

    async def watch(self, websocket: WebSocket, sessions: sessionmaker[Session],
                    user_id: int, token_id: int) -> str:
        """Return (after closing the socket with 1008) once the login no longer holds;
        run it beside the socket's own tasks and end the connection when it returns."""
        event = asyncio.Event()
        entry = (asyncio.get_running_loop(), event)
        self._watchers.setdefault(user_id, set()).add(entry)
        try:
            while True:
                try:
                    await asyncio.wait_for(event.wait(), RECHECK_S)
                except TimeoutError:
                    pass
                event.clear()
                why = await asyncio.to_thread(login_problem, sessions, token_id)
                if why is not None:
                    break
        finally:
            watchers = self._watchers.get(user_id)
            if watchers is not None:
                watchers.discard(entry)
                if not watchers:
                    self._watchers.pop(user_id, None)
        log.info("closing a WebSocket of user %d: %s", user_id, why)
        if websocket.application_state == WebSocketState.CONNECTED:
            try:
                await websocket.close(code=1008, reason=why)
            except RuntimeError:
                pass  # the client went at the same moment
        return why
