"""Reading a file handed to hybridteam: a regular file of a bounded size, or one message.

A path on the command line or in a model can name anything: a FIFO (reading blocks
forever), a character device (``/dev/zero`` never ends, ``/dev/urandom`` neither), a
file of gigabytes. Each kind of file has a size it is read up to, raised by an
environment variable, and everything else is refused before a byte is read.
"""

from __future__ import annotations

import math
import os
import stat

from hybridteam.io.yamlpos import SourceError

#: megabytes of a trace, or of a file of a run folder, read back (HYBRIDTEAM_MAX_TRACE_MB
#: raises it): a run within the default memory limit writes a few hundred megabytes at
#: most, and reading one costs about twice its size in memory
MAX_TRACE_MB = 500.0


def _limit(name: str, env: str, default: float) -> float:
    """Megabytes to read: ``env``'s value if set, else ``default``."""
    text = os.environ.get(env)
    if not text:
        return default
    try:
        limit = float(text)
    except ValueError:
        limit = math.nan
    if not 0 < limit < math.inf:
        raise SourceError(
            name, message=f"cannot read file: {env}={text!r} must be a number of megabytes > 0"
        )
    return limit


def read_regular(
    path: str | os.PathLike[str], name: str, *, limit_mb: float, env: str, what: str
) -> bytes:
    """The bytes of the regular file ``path`` (called ``name`` in messages), at most
    ``limit_mb`` megabytes (``env`` raises it); else a :class:`SourceError` saying why.
    ``what`` names the kind of file, plural ("model files")."""
    try:
        info = os.stat(path)
    except OSError as exc:
        raise SourceError(name, message=f"cannot read file: {exc.strerror or exc}") from None
    if stat.S_ISDIR(info.st_mode):
        raise SourceError(name, message="cannot read file: it is a directory")
    if not stat.S_ISREG(info.st_mode):
        kind = "a FIFO" if stat.S_ISFIFO(info.st_mode) else "a device or socket"
        raise SourceError(name, message=f"cannot read file: it is {kind}, not a regular file")
    limit = _limit(name, env, limit_mb)
    too_large = SourceError(
        name,
        message=f"file is {info.st_size / 1e6:.1f} MB; {what} are "
        f"read up to {limit:g} MB (set {env} to read larger ones)",
    )
    if info.st_size > limit * 1e6:
        raise too_large
    try:
        with open(path, "rb") as handle:
            data = handle.read(int(limit * 1e6) + 1)  # the file may have grown since
    except OSError as exc:
        raise SourceError(name, message=f"cannot read file: {exc.strerror or exc}") from None
    if len(data) > limit * 1e6:
        raise too_large
    return data
