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

__all__ = ["CommandParser", "renamed", "option_names", "unknown_options"]


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser whose unknown options get the close known ones as a suggestion (of
    the subcommand they were given to), a usage error with exit status 2 as argparse's own,
    in one message with argparse's own problems (an invalid value, a required option missing:
    named after the unknown options, which may be their cause)."""

    _unknown = ""          # the unknown options of this parser's command line, as a sentence

    def parse_args(self, args=None, namespace=None):
        argv = list(sys.argv[1:] if args is None else args)
        parser, rest = _subcommand(self, argv)
        unknown = [tok.split("=", 1)[0] for tok in _options(rest) if not _known(parser, tok.split("=", 1)[0])]
        parser._unknown = unknown_options(parser, unknown) if unknown else ""
        parsed, extras = self.parse_known_args(argv, namespace)
        if parser._unknown:
            parser.error("")
        if extras:
            parser.error("; ".join(f"unexpected argument {extra!r}" for extra in extras))
        return parsed

    def error(self, message):
        unknown, self._unknown = self._unknown, ""
        if unknown:
            message = f"{unknown}; {message}" if message else unknown
        super().error(message)


def _subcommand(parser: argparse.ArgumentParser, argv: list) -> tuple:
    """(the parser of the (sub)subcommand ``argv`` names, the tokens after its name)."""
    action = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    if action is None:
        return parser, argv
    for i, token in enumerate(argv):
        if token == "--":
            break
        if not token.startswith("-") and token in action.choices:
            return _subcommand(action.choices[token], argv[i + 1:])
    return parser, argv


def _options(tokens: list) -> list:
    """The tokens that are long options (up to a ``--`` that ends the options)."""
    out = []
    for token in tokens:
        if token == "--":
            break
        if token.startswith("--"):
            out.append(token)
    return out


def _known(parser: argparse.ArgumentParser, flag: str) -> bool:
    """``flag`` is an option of ``parser`` or the prefix argparse completes (an ambiguous prefix
    is argparse's own error)."""
    options = parser._option_string_actions
    return flag in options or (parser.allow_abbrev and any(o.startswith(flag) for o in options))


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


def unknown_options(parser: argparse.ArgumentParser, unknown: list) -> str:
    """One sentence per unknown option: its close known ones and the options of the command."""
    names = option_names(parser)
    known = ", ".join(sorted(set(names.values())))
    parts = []
    for flag in dict.fromkeys(unknown):
        found = list(dict.fromkeys(names[m] for m in close_matches(flag, list(names))))
        hint = (": did you mean " + " or ".join(found) + "?") if found else ""
        parts.append(f"unknown option {flag}{hint}")
    return "; ".join(parts) + f" (options of {parser.prog}: {known})"


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
