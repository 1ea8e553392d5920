"""A series Lambda's coefficients tabulated over a box of its two inputs (shadowing/smith.py).

The host's rule costs some 30-40 us per parameter vector (the integrand at every pair of series
node and rule node, with its derivatives), and a fit of a database asks for tens of thousands of
new vectors.  A table of the coefficients c_k and their derivatives by each input at a grid of
nodes, made once per machine from the rule (brdfcl._cache.generated_arrays), is interpolated
instead: bicubic Hermite on the values and the rule's first derivatives (the cross derivative by
central differences of the first), in the log of an input searched in log space (``log``).  The
derivatives returned are the interpolant's own, so that values and Jacobian agree as exactly as
the rule's do.  Vectors outside the box get the rule itself (``covers``).

Its error against the rule, in G1 = 1 / (1 + Lambda) over theta_o <= 80 deg, is checked over the
box by tests/test_series_table.py (bound ``MAX_G1_ERROR``), far below the series' own error
against the exact Lambda (bench/results/lambda_gtr.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_G1_ERROR = 1e-5
"""The most a table may move G1 = 1 / (1 + Lambda) from the rule's, relatively, over theta_o <= 80 deg."""


@dataclass(frozen=True)
class Box:
    """The region tabulated: ``lo``, ``hi`` per input, ``log`` whether that axis is the input's
    logarithm, ``nodes`` the grid's nodes per axis (the ends included)."""

    lo: tuple[float, float]
    hi: tuple[float, float]
    log: tuple[bool, bool]
    nodes: tuple[int, int]

    def key(self) -> str:
        return repr((self.lo, self.hi, self.log, self.nodes))

    def axes(self) -> list[np.ndarray]:
        """The nodes of each axis, in the axis's own variable (the log where ``log``)."""
        return [np.linspace(*self._ends(j), self.nodes[j]) for j in range(2)]

    def _ends(self, j: int) -> tuple[float, float]:
        f = np.log if self.log[j] else float
        return float(f(self.lo[j])), float(f(self.hi[j]))


HERMITE = np.array([[1.0, 0.0, -3.0, 2.0],      # value at 0: 1 - 3 t^2 + 2 t^3
                    [0.0, 1.0, -2.0, 1.0],      # slope at 0: t - 2 t^2 + t^3
                    [0.0, 0.0, 3.0, -2.0],      # value at 1: 3 t^2 - 2 t^3
                    [0.0, 0.0, -1.0, 1.0]])     # slope at 1: t^3 - t^2
"""The cubic Hermite bases (rows) as coefficients of 1, t, t^2, t^3 (columns)."""


class CoefficientTable:
    """``rule(rows)`` ((m, 2) input rows -> (m, 3, K): the K coefficients and their derivatives by
    each input) tabulated over ``box``; ``arrays``: what `build` made (from brdfcl's cache): per
    grid cell the bicubic's coefficients of s^a t^b (s, t in [0, 1] across the cell)."""

    def __init__(self, box: Box, arrays: dict):
        self.box = box
        self.x, self.y = box.axes()
        self.poly = arrays["poly"]                     # (nx - 1, ny - 1, 4, 4, K)

    @staticmethod
    def build(box: Box, rule, chunk: int = 4096) -> dict:
        """The arrays of a table: at every node the coefficients (nx, ny, K) and their derivatives by
        each axis' variable from the rule, the cross derivative by central differences of the
        first, made into each cell's bicubic Hermite polynomial."""
        x, y = box.axes()
        gx, gy = np.meshgrid(x, y, indexing="ij")
        rows = np.stack([np.exp(gx.ravel()) if box.log[0] else gx.ravel(),
                         np.exp(gy.ravel()) if box.log[1] else gy.ravel()], axis=1)
        made = np.concatenate([rule(rows[i:i + chunk]) for i in range(0, len(rows), chunk)])
        shape = (box.nodes[0], box.nodes[1], made.shape[-1])
        hx, hy = x[1] - x[0], y[1] - y[0]
        f = made[:, 0].reshape(shape)
        # d/d ln a = a d/da on a log axis; slopes in units of a cell
        fx = (made[:, 1] * (rows[:, :1] if box.log[0] else 1.0)).reshape(shape) * hx
        fy = (made[:, 2] * (rows[:, 1:] if box.log[1] else 1.0)).reshape(shape) * hy
        fxy = np.gradient(fx, axis=1, edge_order=2)
        # per cell, G[u, v]: u, v the Hermite data along x and y (value at 0, slope at 0, value at 1,
        # slope at 1); the polynomial's coefficients are HERMITE^T G HERMITE
        data = {(False, False): f, (True, False): fx, (False, True): fy, (True, True): fxy}
        ends = ((0, False), (0, True), (1, False), (1, True))
        g = np.empty((shape[0] - 1, shape[1] - 1, 4, 4, shape[2]))
        for u, (di, slope_x) in enumerate(ends):
            for v, (dj, slope_y) in enumerate(ends):
                g[:, :, u, v] = data[slope_x, slope_y][di:di + shape[0] - 1, dj:dj + shape[1] - 1]
        return {"poly": np.einsum("ua,ijuvk,vb->ijabk", HERMITE, g, HERMITE)}

    def covers(self, rows: np.ndarray) -> np.ndarray:
        """(m,) whether each input row lies inside the box (NaN does not)."""
        lo, hi = np.asarray(self.box.lo), np.asarray(self.box.hi)
        return np.all((rows >= lo) & (rows <= hi), axis=1)

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        """(m, 3, K) at rows inside the box: the interpolated coefficients and their derivatives by
        each input."""
        box = self.box
        at, powers, slopes = [], [], []
        for k, axis in enumerate((self.x, self.y)):
            v = np.log(rows[:, k]) if box.log[k] else rows[:, k]
            h = axis[1] - axis[0]
            i = np.clip(np.floor((v - axis[0]) / h).astype(np.intp), 0, axis.size - 2)
            t = (v - axis[i]) / h
            at.append(i)
            powers.append(np.stack([np.ones_like(t), t, t * t, t * t * t], axis=1))
            slopes.append(np.stack([np.zeros_like(t), np.ones_like(t), 2 * t, 3 * t * t], axis=1) / h)
        poly = self.poly[at[0], at[1]]                  # (m, 4, 4, K)
        out = np.empty((rows.shape[0], 3, poly.shape[-1]))
        out[:, 0] = np.einsum("ma,mabk,mb->mk", powers[0], poly, powers[1])
        out[:, 1] = np.einsum("ma,mabk,mb->mk", slopes[0], poly, powers[1])
        out[:, 2] = np.einsum("ma,mabk,mb->mk", powers[0], poly, slopes[1])
        for k in range(2):                               # d/da = (d/d ln a) / a on a log axis
            if box.log[k]:
                out[:, 1 + k] /= rows[:, k:k + 1]
        return out


