"""Dask: a cluster run gives the in-process results; a worker killed mid-run loses nothing."""
import json
import os
import signal

import pytest

pytest.importorskip("distributed")

from brdfcl.app.cluster import make_client  # noqa: E402
from brdfcl.app.run import fit_all  # noqa: E402

# -n with --dist loadgroup (the slow tier in .ci/run): one process runs this module's tests
pytestmark = pytest.mark.xdist_group("test_cluster")

NAMES = ["synth-fabric", "synth-mirror", "synth-smooth-plastic", "synth-rough-metal"]
MODEL = "diffuse+ggx"


@pytest.fixture(scope="module")
def client():
    c = make_client(workers=2)
    yield c
    c.close()


def _params(out):
    return {n: json.loads((out / f"{n}.json").read_text())["params"] for n in NAMES}


def test_cluster_matches_in_process(client, demo_db, tmp_path):
    paths = [demo_db / f"{n}.binary" for n in NAMES]
    here = fit_all(paths, tmp_path / "local", model=MODEL)
    there = fit_all(paths, tmp_path / "cluster", model=MODEL, client=client, batch=1)
    assert here.ok and there.ok and len(there.results) == 4
    a, b = _params(tmp_path / "local"), _params(tmp_path / "cluster")
    for n in NAMES:
        for k in a[n]:
            assert b[n][k]["value"] == pytest.approx(a[n][k]["value"], rel=1e-9), (n, k)
    assert (tmp_path / "cluster" / "summary.csv").read_text().count("\n") == 5


@pytest.mark.slow
def test_worker_killed_mid_run(client, demo_db, tmp_path):
    paths = [demo_db / f"{n}.binary" for n in NAMES]
    pids = list(client.run(os.getpid).values())
    killed = []

    def log(msg):
        if msg.startswith("cluster:") and not killed:
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])
    rep = fit_all(paths, tmp_path / "o", model=MODEL, client=client, batch=1, log=log)
    assert killed
    assert sorted(r.name for r in rep.results) == sorted(NAMES)       # every result exactly once
    assert sorted(p.stem for p in (tmp_path / "o").glob("*.json")) == sorted(NAMES)

