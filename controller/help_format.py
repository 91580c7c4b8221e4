"""Command-line help that shows each option's default value, not the name it comes from.

`exostudy virtual-study --help` once said "(default:
backend.analysis.virtual_study.DEFAULT_SPEED)": true, and useless to someone deciding
what to type. Every `exostudy` parser (the backend's and the controller's own) uses this
formatter, so an option with a default states it as a value.
"""

from __future__ import annotations

import argparse
import copy


def _has_default(action: argparse.Action) -> bool:
    """An option whose default is a value worth stating (not None, not a flag's False)."""
    d = action.default
    return (bool(action.option_strings) and not action.required and d is not None
            and d is not False and d is not argparse.SUPPRESS)


class DefaultsHelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions kept as written; every option with a default (not None, not a
    flag's False) ends its help with "(default: VALUE)" unless the help states one."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "%(default)" in text or "(default" in text or not _has_default(action):
            return action.help
        return f"{text} (default: %(default)s)".lstrip()

    def _format_action(self, action: argparse.Action) -> str:
        # argparse prints no help line for an option without help text: give a copy of
        # such an option its default as its help, so the value is still shown.
        if not action.help and _has_default(action):
            action = copy.copy(action)
            action.help = "(default: %(default)s)"
        return super()._format_action(action)
