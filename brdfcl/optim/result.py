"""What the stages and the fit return: `StageResult` (one stage, a batch of materials) and
`FitResult` (one material's fit), both in the manner of scipy.optimize.OptimizeResult."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from brdfcl.optim.status import Status, message


@dataclass
class StageResult:
    """One stage's outcome for a batch of materials, as scipy's OptimizeResult but batched: row j
    is a solution for material ``mat[j]`` (a stage may return several per material, or only some
    materials).  ``x`` is in the optimiser's space (brdfcl.optim.spaces); ``nfev`` counts the
    stage's evaluations per material of the batch, whichever row they served."""

    x: np.ndarray                   # (m, k) optimiser space
    fun: np.ndarray                 # (m,) loss of each row on the stage's cell set (inf: none found)
    mat: np.ndarray                 # (m,) material (index in the batch) of each row
    nfev: np.ndarray                # (n,) evaluations per material of the batch
    status: list[Status]            # (m,) how each row ended (brdfcl.optim.status)
    success: np.ndarray             # (m,) bool
    message: str = ""               # one line about the stage
    errors: dict[str, np.ndarray] = field(default_factory=dict)   # error evaluation: (m,) per name
    bounds_hit: list[list[str]] = field(default_factory=list)     # error evaluation: names per row
    notes: list[str] = field(default_factory=list)                # (m,) what a stage adds to a row's message

    def note(self, j: int) -> str:
        return self.notes[j] if self.notes else ""

    def row_message(self, j: int) -> str:
        """Row j's status in words, with its note."""
        return message(self.status[j], self.note(j))

    def rows(self, sel: np.ndarray | list[int]) -> StageResult:
        """The rows ``sel`` of this result (same nfev, message)."""
        sel = np.asarray(sel, dtype=int)
        return StageResult(self.x[sel], self.fun[sel], self.mat[sel], self.nfev, [self.status[j] for j in sel],
                           self.success[sel], self.message, {k: e[sel] for k, e in self.errors.items()},
                           [self.bounds_hit[j] for j in sel] if self.bounds_hit else [],
                           [self.note(j) for j in sel])


@dataclass
class FitResult:
    """One material's fit, in the spirit of scipy.optimize.OptimizeResult."""

    name: str
    model: str
    metric: str
    params: dict                     # natural values by parameter name
    success: bool
    status: int                      # brdfcl.optim.status.Status: > 0 converged, 0 the iteration limit
    message: str                     # the status in words
    loss: float                      # sum w r^2 in the fit metric, full table
    errors: dict                     # rmse_l2, rmse_log, rmse_cbrt, rel_rmse
    seconds: float                   # its share of the batch's wall time (each launch's split among its materials)
    nfev: int                        # evaluations of this material in the search and refinement (coarse and full)
    history: list                    # [(seconds, stage, rmse in the fit metric)]
    bounds_hit: list
    stages: dict                     # seconds per stage (shared by the batch)
    # assessment (brdfcl.optim.assessment), in NAME.json's form; None / empty when not assessed
    uncertainty: dict | None = None  # {"std_error": {name: float|None}, "correlation": {...}, "method"}
    albedo: dict | None = None       # {"theta_i_deg": [...], "channels": [[one per channel] per angle]}
    flags: list = field(default_factory=list)   # one line per reason not to trust the fit
    lambdas: tuple | None = None     # the channels' wavelengths (um) when not a MERL table's R, G, B

    def as_dict(self) -> dict:
        return asdict(self)
