"""brdfcl.data.sobol: scipy's scrambled Sobol points, made once per machine and kept."""
import subprocess
import sys

import numpy as np


def test_points_are_scipys_and_kept(tmp_path, monkeypatch):
    from scipy.stats import qmc

    from brdfcl.data import sobol
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    made = sobol.sobol_points(7, 64, 3)
    np.testing.assert_array_equal(made, qmc.Sobol(7, scramble=True, seed=3).random(64))
    kept = list((tmp_path / "generated" / "sobol").glob("*.npz"))
    assert len(kept) == 1
    np.testing.assert_array_equal(sobol.sobol_points(7, 64, 3), made)
    assert not np.array_equal(sobol.sobol_points(7, 64, 4), made)
    kept[0].write_bytes(b"not an npz")                # a damaged file is made again
    np.testing.assert_array_equal(sobol.sobol_points(7, 64, 3), made)


def test_a_process_that_finds_them_does_not_import_scipy_stats(tmp_path):
    """Importing scipy.stats costs a process most of a second: points already kept need none."""
    code = ("import sys; from brdfcl.data.sobol import sobol_points; p = sobol_points(5, 32, 0); "
            "print(p.shape, 'scipy.stats' in sys.modules)")
    env = {"BRDFCL_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert first.stdout.split() == ["(32,", "5)", "True"]
    assert second.stdout.split() == ["(32,", "5)", "False"]
