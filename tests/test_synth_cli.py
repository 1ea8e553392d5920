import json
import subprocess
import sys

import numpy as np
import pytest

from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import read_merl
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.synth import DEMO


def run(*args):
    return subprocess.run([sys.executable, "-m", "brdfcl.app.cli", *args], capture_output=True, text=True)


def test_demo_database_matches_its_truth(demo_db):
    truth = json.loads((demo_db / "truth.json").read_text())["materials"]
    assert set(truth) == set(DEMO)
    g = table_geometry()
    idx = np.flatnonzero(g.above_horizon)[::997]
    for name, t in truth.items():
        table = read_merl(demo_db / f"{name}.binary")
        assert table.n_missing == (~g.above_horizon).sum()
        model = Model(t["model"])
        v = np.array([t["params"][n] for n in model.names])
        expect = model.reference(Cells.from_geometry(g, idx), v, False)
        np.testing.assert_allclose(table.brdf()[:, idx], expect, rtol=1e-12)


def test_synth_noise_and_missing(tmp_path):
    r = run("synth", str(tmp_path), "--materials", "synth-fabric", "--noise", "0.05", "--missing", "0.02")
    assert r.returncode == 0, r.stderr
    t = read_merl(tmp_path / "synth-fabric.binary")
    horizon = (~table_geometry().above_horizon).sum()
    assert t.n_missing > horizon + 0.015 * t.stored.shape[1]


@pytest.mark.slow
def test_cli_info_and_errors(tmp_path):
    r = run("info")
    assert r.returncode == 0 and "float64" in r.stdout and "PoCL" in r.stdout
    r = run("synth", str(tmp_path), "--materials", "nope")
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "unknown demo material" in r.stderr and "synth-mirror" in r.stderr
    r = run("info", "--device", "no-such-device")
    assert r.returncode == 2 and "no OpenCL device matches" in r.stderr and "Traceback" not in r.stderr


def test_demo_database_lives_in_brdfcls_cache(tmp_path, monkeypatch):
    """One variable moves all of brdfcl's cache, the demo database included: BRDFCL_CACHE_DIR."""
    from brdfcl.model import synth
    written = []
    monkeypatch.setattr(synth, "write_synth", lambda out, log=None: written.append(out))
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("BRDFCL_CACHE", str(tmp_path / "old"))           # no longer read
    assert synth.demo_dir() == tmp_path / "cache" / "demo"
    assert written == [tmp_path / "cache" / "demo"]
