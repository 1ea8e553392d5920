"""What every reader returns: one material's measured BRDF, as a `Measurement` on a `Layout`.

A fit needs of a measurement only where its cells are and what was measured there: each cell's
geometry (sin th, cos th, cos td, cos ti, cos to), the measure of the (wi, wo) domain it stands
for, and one value per channel, each channel with its wavelength (the diffraction lobe needs
it).  A `Layout` holds the cells; a `Measurement` the values on them.  Measurements of one table
format share one layout object (every MERL table has the same 1.5M cells), so a batch of them
uploads its geometry once; a scattered measurement (a gonioreflectometer's samples) has a layout
of its own.  Whether a layout is ``dense`` decides how a fit uses it: a dense one (a table) is
searched on a coarse subset and refined first on every n-th cell; the cells of a sparse one are
few enough to be used whole in every stage.

A new format is a reader returning a Measurement (with its layout) and its suffix in
brdfcl.data.readers.READERS; nothing above this layer tells formats apart.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

RGB_WAVELENGTHS_UM = {"R": 0.645, "G": 0.526, "B": 0.444}
"""Effective wavelengths (um) of RGB channels: the ones the diffraction lobe uses for MERL tables
(``rgb.effective_wavelengths`` computes what sRGB under D65 gives, for comparison)."""


@dataclass(frozen=True)
class Channel:
    """One measured band: a name (``"R"``, ``"550nm"``) and its (effective) wavelength in um."""

    name: str
    wavelength_um: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.wavelength_um) and self.wavelength_um > 0):
            raise ValueError(f"channel {self.name!r}: wavelength {self.wavelength_um} um must be positive")


def rgb_channels() -> tuple[Channel, Channel, Channel]:
    """The R, G, B channels with the effective wavelengths of ``RGB_WAVELENGTHS_UM``."""
    w = RGB_WAVELENGTHS_UM
    return Channel("R", w["R"]), Channel("G", w["G"]), Channel("B", w["B"])


def cell_rows(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, ...]:
    """(sin th, cos th, cos td, cos ti, cos to) of direction pairs (n = z), float64: the per-cell
    quantities every lobe reads (brdfcl.model.lobes.cells.Cells), from h = (wi + wo) / |wi + wo|."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    ch = h[..., 2]
    sh = np.sqrt(np.maximum(1.0 - ch * ch, 0.0))
    cd = np.sum(wi * h, axis=-1)
    return sh, ch, cd, wi[..., 2], wo[..., 2]


class Layout(ABC):
    """Where a measurement's cells are: their geometry and measure, and which of them a fit uses.

    Cells are numbered 0 .. n-1 in the layout's own order; an index array picks some."""

    dense: bool = False
    """A table's many regular cells: a fit searches a coarse subset (`coarse`) and refines on every
    n-th cell first.  False: every stage uses all of the fitted cells."""

    @abstractmethod
    def select(self, cutoff_deg: float | None) -> np.ndarray:
        """The cells a fit uses: above the horizon, theta_i and theta_o below the cut-off (None:
        90 deg)."""

    @abstractmethod
    def weights(self, index: np.ndarray, cutoff_deg: float | None) -> np.ndarray:
        """The measure (sr^2) of the (wi, wo) domain each cell of ``index`` stands for, within the
        cut-off's domain, float64."""

    @abstractmethod
    def rows(self, index: np.ndarray) -> tuple[np.ndarray, ...]:
        """(sin th, cos th, cos td, cos ti, cos to) of the cells ``index``, float64."""

    def lookup(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray | None:
        """The cell whose bin holds each direction pair (n,), -1 where none does; None for a layout
        that is not a table (scattered samples have no bins to look up)."""
        return None

    def coarse(self, index: np.ndarray, stride: int, peak_bins: int,
               peak_stride: int) -> tuple[np.ndarray, np.ndarray]:
        """A subset of ``index`` for the global search and each cell's weight scale (so that its
        loss estimates the whole's); a sparse layout keeps every cell."""
        return index, np.ones(index.size)


class Measurement(ABC):
    """One material's measured BRDF (1/sr) at the cells of its layout, in its channels.

    ``name`` names its results (NAME.json); ``path`` is the file it was read from (None: made in
    memory)."""

    name: str
    path: str | None
    channels: tuple[Channel, ...]

    @property
    @abstractmethod
    def layout(self) -> Layout:
        """The cells it was measured at (shared by every measurement of a table format)."""

    @abstractmethod
    def values_at(self, indices: Sequence[np.ndarray], outs: Sequence[np.ndarray]) -> None:
        """The BRDF at each index set into ``outs`` ((C, n_i) arrays of any float type), NaN where
        missing.  A file read only now raises its one-line error (DataError, MerlError)."""

    @property
    def n_channels(self) -> int:
        return len(self.channels)

    @property
    def wavelengths(self) -> np.ndarray:
        """Each channel's wavelength (um), float64 (C,)."""
        return np.array([c.wavelength_um for c in self.channels], dtype=np.float64)

    def batch_key(self) -> tuple:
        """Measurements of one key are fitted in one batch: the same channels and, for a dense
        layout, the same layout (one upload of its geometry)."""
        layout = id(self.layout) if self.layout.dense else "sparse"
        return tuple(float(x) for x in self.wavelengths), layout
