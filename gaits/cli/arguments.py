"""Argument types of the ``nhgait`` command line: a malformed number is argparse's usage error
(exit status 2, the option named), never an exception inside a command."""
from __future__ import annotations

import argparse

__all__ = ["positive_int", "workers"]


def positive_int(text: str) -> int:
    """A whole number ≥ 1 (``--max-guesses``, ``--repeats``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def workers(text: str):
    """``auto`` or a whole number ≥ 1 (``plan --workers``)."""
    return text if text == "auto" else positive_int(text)
