"""Files read as data: a scene or a URDF is a regular file of bounded size holding UTF-8 text.

:func:`read_text_file` is the one way nhgait reads a file a user names (scenes, URDFs, a
previous ``solution.json``). Every refusal is one :class:`~nhgait.dynamics.errors.ModelError`
(exit status 2) naming the file and the problem:

* not a regular file — a directory, a FIFO (which would block the reader for ever), a socket or
  a device (``/dev/zero`` never ends); the file is opened without blocking
  (``O_NONBLOCK``) and checked on the open descriptor, so a file swapped for a FIFO after the
  check cannot block either;
* larger than :data:`MAX_TEXT_BYTES` (4 MiB: the largest URDF of example-robot-data, TIAGo's
  dual-arm model, is 0.21 MB; a written scene is a few kB) — at most that many bytes are read,
  whatever the file claims to hold (``/proc`` files claim 0);
* unreadable (an I/O error such as ``/proc/self/mem``'s, a permission);
* not UTF-8 — the error names the first byte that is not, with its line and column, and says
  when the file looks like UTF-16 (a byte-order mark) or Latin-1; a UTF-8 byte-order mark is
  accepted and dropped.
"""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from ...errors import ModelError

__all__ = ["read_text_file", "names_a_file", "decode_utf8", "MAX_TEXT_BYTES"]

#: the largest scene or URDF file read (bytes)
MAX_TEXT_BYTES = 4 * 1024 * 1024

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def read_text_file(path, what: str = "file", *, limit: int = MAX_TEXT_BYTES, title: str | None = None) -> str:
    """The UTF-8 text of the regular file ``path`` (at most ``limit`` bytes); ``what`` names
    it in errors ("scene file", "URDF"). Raises :class:`ModelError` (see the module docstring)."""
    path = Path(path)
    title = title or f"cannot read the {what}"
    data = _read_bytes(path, what, limit, title)
    return decode_utf8(data, f"{what} {path}", title)


def names_a_file(path) -> bool:
    """Is there anything at ``path`` — a link too, even a broken one or a loop? A name the
    system cannot take (too long) counts as a file's name, for the reader to refuse."""
    try:
        return os.path.lexists(path)
    except (OSError, ValueError):
        return True


def _read_bytes(path: Path, what: str, limit: int, title: str) -> bytes:
    try:
        _refuse_kind(os.stat(path).st_mode, path, what, title)     # a socket cannot even be opened
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise ModelError([f"{what} {path} does not exist"], title=title) from None
    except ModelError:                  # _refuse_kind's own answer (a ValueError), not wrapped again
        raise
    except (OSError, ValueError) as exc:
        raise ModelError([f"{what} {path} cannot be opened ({_reason(exc)})"], title=title) from None
    try:
        _refuse_kind(os.fstat(fd).st_mode, path, what, title)      # swapped since the stat: checked again
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise ModelError([f"{what} {path} cannot be read ({_reason(exc)})"], title=title) from None
    finally:
        os.close(fd)
    if size > limit:
        raise ModelError([f"{what} {path} is larger than {limit / 2**20:.0f} MiB, the largest file nhgait "
                          "reads (a scene is a few kB, the largest URDF of example-robot-data 0.21 MB)"],
                         title=title)
    return b"".join(chunks)


def _refuse_kind(mode: int, path: Path, what: str, title: str) -> None:
    """A ModelError unless ``mode`` is a regular file's."""
    if stat.S_ISREG(mode):
        return
    kind = next((label for test, label in _KINDS if test(mode)), "not a regular file")
    raise ModelError([f"{what} {path} is {kind}, not a regular file"], title=title)


def _reason(exc: Exception) -> str:
    if not isinstance(exc, OSError):
        return str(exc)                     # e.g. a NUL character in the name
    return exc.strerror or errno.errorcode.get(exc.errno or 0, type(exc).__name__)


def decode_utf8(data: bytes, where: str, title: str) -> str:
    """``data`` decoded as UTF-8 (a leading byte-order mark dropped); otherwise one
    :class:`ModelError` naming the first byte that is not UTF-8, its line and column."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ModelError([f"{where} is UTF-16 text (it starts with a UTF-16 byte-order mark): save it as "
                          "UTF-8"], title=title)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        start = exc.start
        line = data.count(b"\n", 0, start) + 1
        column = start - (data.rfind(b"\n", 0, start) + 1) + 1
        hint = " (it looks like Latin-1 or Windows-1252 text)" if _latin1_like(data) else ""
        raise ModelError([f"{where} is not UTF-8 text: byte 0x{data[start]:02x} at position {start} "
                          f"(line {line}, column {column}) is not valid UTF-8{hint}; save it as UTF-8"],
                         title=title) from None


def _latin1_like(data: bytes) -> bool:
    """No NUL byte and mostly printable ASCII: 8-bit text in a legacy encoding."""
    return (b"\0" not in data
            and sum(32 <= b < 127 or b in (9, 10, 13) for b in data[:4096]) > 0.9 * min(len(data), 4096))
