"""One vocabulary for the ``nhgait`` command line: the parser class of every (sub)command, which
answers an unknown option with "did you mean …?" like every other nhgait error, and the
former spellings of renamed options, kept one release with a note on stderr.

:class:`CommandParser` is the class of the top parser; argparse gives every subcommand's
parser the same class (``add_subparsers``' default ``parser_class``), so a subcommand added
later (:data:`nhgait.gaits.cli.main.SUBCOMMANDS`) gets the suggestions without a line of its
own. :func:`renamed` adds a former spelling: hidden from ``--help``, the same destination, and
a one-line note when used::

    p.add_argument("--gait", ...)
    renamed(p, "--task", "--gait")     # nhgait sweep --task ... still works, and says so
"""
from __future__ import annotations

import argparse
import sys

from nhgait.dynamics.suggestions import close_matches

__all__ = ["CommandParser", "renamed", "option_names", "unknown_arguments"]


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser whose unknown options get the close known ones as a suggestion (of
    the subcommand they were given to), a usage error with exit status 2 as argparse's own."""

    def parse_args(self, args=None, namespace=None):
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = _subcommand_parser(self, parsed) or self
            parser.error(unknown_arguments(parser, extras))
        return parsed


def _subcommand_parser(parser: argparse.ArgumentParser, parsed) -> argparse.ArgumentParser | None:
    """The parser of the subcommand ``parsed`` ran (None for a parser without subcommands)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            chosen = action.choices.get(getattr(parsed, action.dest, None) or "")
            if chosen is not None:
                return _subcommand_parser(chosen, parsed) or chosen
    return None


def option_names(parser: argparse.ArgumentParser) -> dict:
    """Every option string of ``parser`` → the spelling to suggest (a former spelling → its new
    one; hidden options other than those are left out)."""
    names = {}
    for action in parser._actions:
        for option in action.option_strings:
            if isinstance(action, _Renamed):
                names[option] = action.new
            elif action.help is not argparse.SUPPRESS and option.startswith("--"):
                names[option] = option
    return names


def unknown_arguments(parser: argparse.ArgumentParser, extras: list) -> str:
    """One sentence per unknown argument: an option with its close known ones, a stray value."""
    names = option_names(parser)
    parts = []
    for i, extra in enumerate(extras):
        if not extra.startswith("-"):
            if i == 0 or not extras[i - 1].startswith("-") or "=" in extras[i - 1]:
                parts.append(f"unexpected argument {extra!r}")       # not the value of an unknown option
            continue
        flag = extra.split("=", 1)[0]
        found = list(dict.fromkeys(names[m] for m in close_matches(flag, list(names))))
        hint = (": did you mean " + " or ".join(found) + "?") if found else ""
        known = ", ".join(sorted(set(names.values())))
        parts.append(f"unknown option {flag}{hint} (options of {parser.prog}: {known})")
    return "; ".join(parts)


class _Renamed(argparse.Action):
    """A former spelling: stores into the new option's destination and says so on stderr."""

    def __init__(self, option_strings, dest, new: str = "", **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"nhgait: warning: {option_string} is deprecated: it is spelled {self.new} now (the same "
              f"meaning, as in every other command); {option_string} goes in the next release",
              file=sys.stderr)
        setattr(namespace, self.dest, values)


def renamed(parser: argparse.ArgumentParser, old: str, new: str) -> None:
    """Keep ``old`` working as ``new`` for one release (hidden from ``--help``, a note when used)."""
    target = next(a for a in parser._actions if new in a.option_strings)
    parser.add_argument(old, dest=target.dest, action=_Renamed, new=new, default=argparse.SUPPRESS,
                        metavar=target.metavar, help=argparse.SUPPRESS)
