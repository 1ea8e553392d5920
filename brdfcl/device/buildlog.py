"""A failed OpenCL build told in one short line, with its whole log kept in a file.

A compiler's log can run to kilobytes (PoCL repeats it in the error text itself); a user needs the
cause, and a developer the log.  `failure` keeps the full text in brdfcl's cache
(``build-logs/``) and gives the first compiler error line, so that every error message built on
it stays one line of about 200 characters that names the file holding the rest."""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from brdfcl._cache import cache_dir

CAUSE_CHARS = 100
LINE_CHARS = 185                 # an error line without --debug: 200 with "brdfcl: error: " before it
_ERROR = re.compile(r"\b(?:fatal )?error\b[:\s]", re.IGNORECASE)
_WHERE = re.compile(r"^((?:fatal )?error:\s*)\S+:\d+:\d+:\s*(?:(?:fatal )?error:\s*)?", re.IGNORECASE)


def error_text(e) -> str:
    """The text of a pyopencl error (its default str can be a bare object repr)."""
    rec = e.args[0] if e.args else None
    what = getattr(rec, "what", None)
    return str(what() if callable(what) else (what or e))


def cause(text: str) -> str:
    """The first compiler error line of a build's text (else its first line), at most
    CAUSE_CHARS characters: ``error: unknown target CPU 'generic'``."""
    lines = [" ".join(ln.split()) for ln in text.splitlines() if ln.strip()]
    hits = [ln[m.start():] for ln in lines for m in [_ERROR.search(ln)] if m]
    # pyopencl's own "clBuildProgram failed: BUILD_PROGRAM_FAILURE" says only that it failed
    hits = [h for h in hits if "BUILD_PROGRAM_FAILURE" not in h] or hits
    line = hits[0] if hits else (lines[0] if lines else "no build log")
    line = _WHERE.sub(r"\1", line)              # the compiler's temporary file and position
    return line if len(line) <= CAUSE_CHARS else line[:CAUSE_CHARS - 3] + "..."


def keep(text: str, what: str) -> Path | None:
    """Write a build's whole text to ``build-logs/`` in brdfcl's cache; its path, or None when the
    cache cannot be written."""
    digest = hashlib.sha1(f"{what}\0{text}".encode()).hexdigest()[:12]
    path = cache_dir() / "build-logs" / f"{digest}.log"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(f"{what}\n\n{text}\n")
    except OSError:
        return None
    return path


def line(head: str, cause: str, log: Path | str | None = None, tail: str = "") -> str:
    """``head + cause + tail`` and the log's path, at most LINE_CHARS long: the cause is what is
    cut (never the path to the rest, nor what names the model and device)."""
    where = f" (build log: {_short(log)})" if log else ""
    room = max(24, LINE_CHARS - len(head) - len(tail) - len(where))
    if len(cause) > room:
        cause = cause[:room - 3].rstrip() + "..."
    return f"{head}{cause}{tail}{where}"


def _short(path) -> str:
    """A path with the home folder written ``~`` (a shell expands it back)."""
    home = str(Path.home())
    text = str(path)
    return "~" + text[len(home):] if home != "/" and text.startswith(home + "/") else text


@dataclass(frozen=True)
class Failure:
    cause: str                   # one short line: the compiler's first error
    log: Path | None             # the whole text, or None where it could not be written


def failure(e, what: str = "") -> Failure:
    """The cause and the kept log of a failed build (``e`` a pyopencl error, whose text holds
    the build log)."""
    text = error_text(e)
    return Failure(cause(text), keep(text, what))
