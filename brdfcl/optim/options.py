"""What a fit is asked to do: `FitOptions`, one dataclass whose defaults the CLI shows (it defines
none of its own)."""
from __future__ import annotations

from dataclasses import dataclass, field

from brdfcl.data.geometry import DEFAULT_CUTOFF_DEG
from brdfcl.model.compose import DEFAULT_MODEL
from brdfcl.optim.lm import LMOptions

GLOBAL_METHODS = ("lds", "mlsl", "crs2", "none")


@dataclass
class FitOptions:
    """Options of a fit: model and metric, device, global search, local refinement, constraints."""

    model: str = DEFAULT_MODEL
    metric: str = "log"
    cosw: bool = True
    cutoff_deg: float | None = DEFAULT_CUTOFF_DEG
    real: str = "float"
    device: str | None = None
    vector_width: int | None = None     # CPU cells per work-item; None: brdfcl.device.width decides
    global_method: str = "lds"
    n_candidates: int = 256         # lds: Sobol candidates per material
    n_starts: int = 4               # lds: local searches per material
    local_maxeval: int = 200        # per local search (lds) / whole search (mlsl, crs2: x 10)
    coarse_stride: int = 300        # coarse set: every n-th cell outside the peak region,
    coarse_peak_bins: int = 8       # every peak_stride-th cell with theta_h index below peak_bins
    coarse_peak_stride: int = 40    # 5528 cells; 40 and 300, not 5 and 97: docs/fitting.md "The search"
    lm: LMOptions = field(default_factory=LMOptions)
    preview_stride: int = 8         # > 1: LM first on every n-th cell of the table, to convergence,
    preview_final_iter: int = 10    # then at most this many iterations on the full table (1: off)
    seed: int = 0
    fixed: dict = field(default_factory=dict)
    probe_dead_lobes: bool = True   # revive a lobe that ends at zero amplitude at `probes` shapes
    probes: int = 4
    ct_peak: bool = False           # Cook-Torrance carries the specular peak (brdfcl.optim.peak_order)
    ct_peak_global: bool = True     # ... in the global search too (else only in the local stage)

    def __post_init__(self) -> None:
        if self.preview_stride < 1 or self.preview_final_iter < 1:
            raise ValueError(f"preview stride {self.preview_stride} / final iterations {self.preview_final_iter}: "
                             f"must be at least 1")
        if self.global_method not in GLOBAL_METHODS:
            raise ValueError(f"global method '{self.global_method}'; valid: {', '.join(GLOBAL_METHODS)}")
