"""Scrambled Sobol points, made once per machine.

The generator is scipy's (``scipy.stats.qmc.Sobol``, scrambled), but importing scipy.stats costs a
process about 0.7 s (it builds the docstrings of every distribution), more than a global search's
own host work on a database.  The points depend only on their dimension, count and seed (and
scipy's version): they are kept in brdfcl's cache (brdfcl._cache.generated_arrays) and
scipy.stats is imported only where they are made.
"""
from __future__ import annotations

import numpy as np

from brdfcl._cache import generated_arrays

KEEP = 64                         # point sets kept (a few kB each): every form's dimension


def sobol_points(d: int, n: int, seed: int) -> np.ndarray:
    """(n, d) float64 in [0, 1): ``scipy.stats.qmc.Sobol(d, scramble=True, seed=seed).random(n)``."""
    import scipy

    def make() -> dict:
        from scipy.stats import qmc
        return {"points": qmc.Sobol(d, scramble=True, seed=seed).random(n)}
    key = f"d{int(d)}-n{int(n)}-seed{int(seed)}-scipy{scipy.__version__}"
    return generated_arrays("sobol", key, make, keep=KEEP)["points"]
