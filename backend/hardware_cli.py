"""`exostudy hardware ...`: the hardware bring-up from a terminal.

The running server owns the device link (its worker talks to the exoskeleton), so the
command is a client of the server's REST API (`/api/hardware/...`), never a second host
on the link: the same refusals, the same stored profile, the same audit trail as the
console. It logs in with a bearer token: `EXOSTUDY_TOKEN`, else `--user` with the
password from `EXOSTUDY_PASSWORD` or a prompt; a token it got by logging in is revoked
before it exits (a bearer token lasts 30 days, and one per command would pile up),
also when it is stopped by Ctrl-C, SIGTERM or SIGHUP in the middle of a step.
Exit status: 0 the step passed, 1 it ran and failed, 2 the server refused it (the
message says why) or could not be reached.
"""

from __future__ import annotations

import argparse
import getpass
import json
import os
import signal
import sys
import threading
import urllib.error
import urllib.request
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from types import FrameType
from typing import Any

DEFAULT_URL = "http://127.0.0.1:8000"


class ApiError(RuntimeError):
    """The server refused the request (or could not be reached)."""


class Api:
    """A logged-in client of one server."""

    def __init__(self, url: str, token: str, *, owned: bool = False) -> None:
        self.url = url.rstrip("/")
        self.token = token
        #: The token was made by this command's login (`logout` ends it), not given.
        self.owned = owned

    @classmethod
    def login(cls, url: str, user: str | None, password: str | None) -> Api:
        """A token from the environment, else one from logging in as `user` (owned:
        `logout` revokes it)."""
        token = os.environ.get("EXOSTUDY_TOKEN", "")
        if token:
            return cls(url, token)
        if not user:
            raise ApiError("log in: set EXOSTUDY_TOKEN, or give --user (password from "
                           "EXOSTUDY_PASSWORD or a prompt)")
        if password is None:
            password = os.environ.get("EXOSTUDY_PASSWORD") or getpass.getpass(
                f"password for {user}: ")
        out = cls(url, "").call("POST", "/api/auth/token",
                                {"username": user, "password": password})
        return cls(url, str(out["access_token"]), owned=True)

    def logout(self) -> None:
        """Revoke the token this command logged in for (a given token is left alone);
        a server that cannot be reached any more is not an error of the step."""
        if not self.owned:
            return
        try:
            self.call("POST", "/api/auth/logout")
        except ApiError as exc:
            print(f"exostudy hardware: the login token could not be revoked ({exc}); "
                  "it expires in 30 days, or `POST /api/auth/revoke-all` ends it",
                  file=sys.stderr)
        self.owned = False

    def call(self, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
        """JSON in, JSON out; ApiError with the server's own message on a refusal."""
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.url + path, data=data, method=method)
        req.add_header("Accept", "application/json")
        if data is not None:
            req.add_header("Content-Type", "application/json")
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        try:
            # The longest step (a 10 s capture, or a simulator restarting) is well
            # within this; the server answers every step.
            with urllib.request.urlopen(req, timeout=180) as resp:
                return json.loads(resp.read() or b"null")
        except urllib.error.HTTPError as exc:
            try:
                detail = json.loads(exc.read()).get("detail", "")
            except (ValueError, AttributeError):
                detail = ""
            text = detail if isinstance(detail, str) else json.dumps(detail)
            raise ApiError(f"{exc.code}: {text}") from None
        except (urllib.error.URLError, OSError) as exc:
            raise ApiError(f"cannot reach {self.url}: {exc}") from None


def build_parser() -> argparse.ArgumentParser:
    """The `exostudy hardware` parser."""
    p = argparse.ArgumentParser(prog="exostudy hardware", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--url", default=os.environ.get("EXOSTUDY_URL", DEFAULT_URL),
                   help=f"the server (default: EXOSTUDY_URL or {DEFAULT_URL})")
    p.add_argument("--user", default=os.environ.get("EXOSTUDY_USER"),
                   help="account to log in as (default: EXOSTUDY_USER)")
    p.add_argument("--json", action="store_true", help="print the server's answer as JSON")
    sub = p.add_subparsers(dest="step", required=True)
    sub.add_parser("status", help="the bring-up in progress and the profile in effect")
    for name, what in (("zero", "encoder zero at the standing posture"),
                       ("offset", "cam-to-output offset (alpha = 0 while unlocked)")):
        s = sub.add_parser(name, help=what)
        s.add_argument("--seconds", type=float, default=2.0)
    d = sub.add_parser("direction", help="direction of one side: flex that hip meanwhile")
    d.add_argument("--side", choices=("left", "right"), required=True)
    d.add_argument("--seconds", type=float, default=4.0)
    pu = sub.add_parser("pulse", help="solenoid test pulse (nobody wearing the exoskeleton)")
    pu.add_argument("--side", choices=("left", "right"), required=True)
    pu.add_argument("--duration-ms", type=float, default=300.0)
    pu.add_argument("--nobody-wearing", action="store_true",
                    help="confirm that nobody wears the exoskeleton (required)")
    w = sub.add_parser("watchdog", help="time the device's command watchdog")
    w.add_argument("--side", choices=("left", "right"), default="left")
    w.add_argument("--nobody-wearing", action="store_true",
                   help="confirm that nobody wears the exoskeleton (required)")
    r = sub.add_parser("release", help="time the hardware release: stop the heartbeat with "
                       "one side locked, the monitor must cut the drivers")
    r.add_argument("--side", choices=("left", "right"), default="left")
    r.add_argument("--nobody-wearing", action="store_true",
                   help="confirm that nobody wears the exoskeleton (required)")
    sub.add_parser("link", help="link statistics: drops by reason, gaps, timing")
    pr = sub.add_parser("profile", help="finish the bring-up (store the profile), or "
                        "show stored profiles")
    pr.add_argument("--firmware-version", default=None,
                    help="what the firmware reports (real hardware only)")
    pr.add_argument("--list", action="store_true", help="list stored profiles instead")
    pr.add_argument("--show", type=int, default=None, help="show one stored profile")
    return p


def _request(args: argparse.Namespace) -> tuple[str, str, dict[str, Any] | None]:
    step = args.step
    if step == "status":
        return "GET", "/api/hardware", None
    if step in ("zero", "offset"):
        return "POST", f"/api/hardware/{step}", {"seconds": args.seconds}
    if step == "direction":
        return "POST", "/api/hardware/direction", {"side": args.side, "seconds": args.seconds}
    if step == "pulse":
        return "POST", "/api/hardware/pulse", {"side": args.side,
                                               "duration_ms": args.duration_ms,
                                               "nobody_wearing": args.nobody_wearing}
    if step in ("watchdog", "release"):
        return "POST", f"/api/hardware/{step}", {"side": args.side,
                                                 "nobody_wearing": args.nobody_wearing}
    if step == "link":
        return "POST", "/api/hardware/link", None
    if args.list:
        return "GET", "/api/hardware/profiles", None
    if args.show is not None:
        return "GET", f"/api/hardware/profiles/{args.show}", None
    return "POST", "/api/hardware/profile", {"firmware_version": args.firmware_version}


def _profile_lines(p: dict[str, Any]) -> list[str]:
    lines = [f"profile {p['id']}: {p['status']}, device {p['device']} "
             f"{p.get('unique_id') or '-'}, firmware {p['firmware_version']!r}, key id "
             f"{p['key_id'] or '-'}",
             f"  encoder offsets {p['encoder_offsets']}, directions "
             f"{p['encoder_directions']}, cam-output offsets {p['cam_output_offsets']}"]
    for name, s in p["steps"].items():
        lines.append(f"  {name}: {'passed' if s['passed'] else 'FAILED'} - {s['message']}")
    return lines


def _show(args: argparse.Namespace, out: Any) -> int:
    """Print the answer; the exit status of a step is its verdict."""
    if args.json:
        print(json.dumps(out, indent=1))
    if args.step == "status":
        if not args.json:
            print(f"device {out['device']} (simulated: {out['simulated']}); applied offsets "
                  f"{out['applied_offsets']}, directions {out['applied_directions']}")
            print(f"  identity: {out.get('identity') or 'not proved yet'}")
            for key in ("applied_note", "firmware_notice"):
                if out.get(key):
                    print(f"  {out[key]}")
            for label in ("draft", "active"):
                if out[label] is not None:
                    print(f"{label}:")
                    print("\n".join(_profile_lines(out[label])))
        return 0
    if isinstance(out, list):
        if not args.json:
            for p in out:
                print("\n".join(_profile_lines(p)))
        return 0
    if "result" in out:
        r = out["result"]
        if not args.json:
            print(f"{out['step']}: {'passed' if r['passed'] else 'FAILED'} - {r['message']}")
            for k, v in r["values"].items():
                print(f"  {k}: {v}")
        return 0 if r["passed"] else 1
    if not args.json:
        print("\n".join(_profile_lines(out)))
    return 0 if out["status"] in ("complete", "draft") else 1


#: Signals that stop the command as Ctrl-C does: through `finally`, so the token it
#: logged in for is revoked (`kill`, a closed terminal, a supervisor stopping it).
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP")
                     if hasattr(signal, name))


class _Stop:
    """The stop signal received (0: none) and whether the token's revocation is running,
    during which a signal waits instead of cutting it short."""

    def __init__(self) -> None:
        self.signum = 0
        self.cleaning = False


@contextmanager
def _stopping_runs_finally() -> Iterator[_Stop]:
    """While inside: SIGTERM and SIGHUP raise SystemExit(128 + signal), so the caller's
    `finally` (the token's revocation) runs; a signal during that cleanup (`cleaning`)
    or a second one only records itself. The previous handlers come back after, and a
    recorded stop then ends the command."""
    state = _Stop()
    if threading.current_thread() is not threading.main_thread():
        yield state  # handlers can only be set in the main thread
        return

    def stop(signum: int, _frame: FrameType | None) -> None:
        first = not state.signum
        state.signum = state.signum or signum
        if first and not state.cleaning:
            raise SystemExit(128 + signum)

    previous = {sig: signal.signal(sig, stop) for sig in STOP_SIGNALS}
    try:
        yield state
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if state.signum:
        raise SystemExit(128 + state.signum)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `exostudy hardware`."""
    args = build_parser().parse_args(argv)
    method, path, body = _request(args)
    with _stopping_runs_finally() as stopping:
        try:
            api = Api.login(args.url, args.user, None)
        except ApiError as exc:
            print(f"exostudy hardware {args.step}: refused: {exc}", file=sys.stderr)
            return 2
        try:
            out = api.call(method, path, body)
        except ApiError as exc:
            print(f"exostudy hardware {args.step}: refused: {exc}", file=sys.stderr)
            return 2
        finally:
            stopping.cleaning = True
            api.logout()
    return _show(args, out)


if __name__ == "__main__":
    raise SystemExit(main())
