"""The device layer's errors, each one line for the user (the command line prints it as it is)."""
from __future__ import annotations

from pathlib import Path


class DeviceError(RuntimeError):
    """No OpenCL device, or not the one asked for."""


class ProgramError(DeviceError):
    """A program that cannot be built or used on a device; the message is one line.  ``cause``
    is the compiler's first error (or the failing check) alone, ``log`` the file with the whole
    build log (None when there is none)."""

    def __init__(self, message: str, cause: str = "", log: Path | None = None):
        super().__init__(message)
        self.cause = cause or message
        self.log = log
