"""Every `exostudy` help text states default values, never the Python names they come
from (`virtual-study --help` once said "(default:
backend.analysis.virtual_study.DEFAULT_SPEED)")."""

from __future__ import annotations

import argparse
import re

import pytest

from backend.analysis.virtual_study import COLLECTION_SPEED, DEFAULT_SPEED
from backend.cli import build_parser


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _help_of(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """The help an `exostudy ...` command line prints (also for the subcommands with
    their own parsers)."""
    if argv and argv[0] == "device-sim":
        from controller.sim.device_server import main as run
        args = argv[1:]
    elif argv and argv[0] == "replay":
        from controller.runner.replay import main as run
        args = argv[1:]
    else:
        from backend.cli import main as run
        args = argv
    with pytest.raises(SystemExit) as done:
        run([*args, "--help"])
    assert done.value.code == 0
    return capsys.readouterr().out


def _squash(text: str) -> str:
    return re.sub(r"\s+", " ", text)


@pytest.mark.parametrize("command", [[], *([c] for c in _subparsers())],
                         ids=lambda c: " ".join(c) or "exostudy")
def test_every_default_is_shown_as_a_value(command: list[str],
                                           capsys: pytest.CaptureFixture[str]) -> None:
    text = _squash(_help_of(command, capsys))
    assert not re.search(r"\(default: [a-z_]+\.[a-z_.]+[A-Z_]*\)", text), text
    assert "%(" not in text
    if command and command[0] in ("device-sim", "replay"):
        return  # their own parsers, checked by the values below
    parser = build_parser() if not command else _subparsers()[command[0]]
    for action in parser._actions:
        d = action.default
        if not action.option_strings or action.required or d in (None, argparse.SUPPRESS) \
                or d is False:
            continue
        assert re.search(rf"\(default:? {re.escape(str(d))}\)", text), (action.option_strings, d)


def test_the_virtual_study_help_shows_its_speeds(capsys: pytest.CaptureFixture[str]) -> None:
    text = _squash(_help_of(["virtual-study"], capsys))
    assert f"(default: {DEFAULT_SPEED})" in text
    assert f"(default: {COLLECTION_SPEED})" in text
    assert "DEFAULT_SPEED" not in text and "backend." not in text


def test_the_device_and_replay_help_show_their_defaults(
        capsys: pytest.CaptureFixture[str]) -> None:
    from controller.sim.device_server import DEFAULT_PORT

    device = _squash(_help_of(["device-sim"], capsys))
    assert f"UDP port to listen on (default: {DEFAULT_PORT})" in device
    assert "(default: paper-evaluation)" in device
    replay = _squash(_help_of(["replay"], capsys))
    assert "--calibrate-seconds CALIBRATE_SECONDS (default: 2.0)" in replay
