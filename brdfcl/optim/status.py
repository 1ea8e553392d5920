"""How a fit ended: integer codes with messages, as scipy.optimize's ``status`` and ``message``.

A code > 0 is a converged fit, 0 the iteration limit, < 0 a row that is not a refined fit (a
start, one still running, one that failed).  Decisions read the code (``Status.converged``);
the message says it to a user, with a note where a stage adds one (``message``)."""
from __future__ import annotations

from enum import IntEnum


class Status(IntEnum):
    """The outcome of one row of a stage, and of a material's fit (FitResult.status)."""

    BEHIND = -4              # stopped: still above another candidate's error after BEHIND_AFTER iterations
    FAILED = -3              # the fit's loss or errors are not finite
    RUNNING = -2             # still iterating (inside a stage only)
    START = -1               # a start: the global search's, or given (no refinement yet)
    ITERATION_LIMIT = 0
    FTOL = 1                 # three accepted steps each lowering the loss by less than ftol
    PREDICTED_FTOL = 2       # even an undamped Gauss-Newton step would gain less than ftol
    NOISE_FLOOR = 3          # the loss reached the float32 noise floor
    NO_DECREASE = 4          # no step lowers the loss any more
    SETTLED = 5              # converged on the preview cells; the full table's capped iterations changed it little

    @property
    def converged(self) -> bool:
        return self > 0

    @property
    def text(self) -> str:
        return MESSAGES[self]


MESSAGES = {
    Status.BEHIND: "stopped: far behind another candidate",
    Status.FAILED: "failed: the error is not finite",
    Status.RUNNING: "running",
    Status.START: "start",
    Status.ITERATION_LIMIT: "iteration limit",
    Status.FTOL: "converged (ftol)",
    Status.PREDICTED_FTOL: "converged (predicted decrease below ftol)",
    Status.NOISE_FLOOR: "converged (at the noise floor)",
    Status.NO_DECREASE: "converged (no further decrease)",
    Status.SETTLED: "converged on the preview cells",
}
"""Each code's message."""


def message(code: int, note: str = "") -> str:
    """A code's message, with a stage's note after it (``converged (ftol); after reviving a lobe``)."""
    text = MESSAGES[Status(code)]
    return f"{text}; {note}" if note else text
