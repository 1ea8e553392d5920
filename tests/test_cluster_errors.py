"""A failure inside a Dask worker reaches the user as one line naming the materials, the worker and
the cause; --debug shows the worker's traceback; Dask's own logs stay quiet."""
import pickle
import subprocess
import sys

import pytest

pytest.importorskip("distributed")

import pyopencl as cl  # noqa: E402

import brdfcl.app.cluster  # noqa: E402
import brdfcl.optim.fit  # noqa: E402
from brdfcl.app.cluster import RemoteTraceback, WorkerError, describe_error, fit_chunk, make_client  # noqa: E402
from brdfcl.app.run import fit_all  # noqa: E402
from brdfcl.optim.fit import FitOptions  # noqa: E402

CLI = [sys.executable, "-m", "brdfcl.app.cli"]
NAMES = ["synth-fabric", "synth-mirror"]


@pytest.fixture()
def db(demo_db, tmp_path):
    d = tmp_path / "db"
    d.mkdir()
    for n in NAMES:
        (d / f"{n}.binary").symlink_to(demo_db / f"{n}.binary")
    return d


def pyopencl_error():
    """A real pyopencl.LogicError: its argument is an _ErrorRecord, which does not pickle."""
    ctx = cl.Context([brdfcl.device.platforms.pick_device()[1]])
    try:
        cl.Buffer(ctx, cl.mem_flags.READ_ONLY, 0)
    except cl.Error as e:
        return e
    raise AssertionError("a zero-size buffer was accepted")


@pytest.mark.slow
def test_cli_worker_failure_is_one_line(db, tmp_path):
    args = ["fit-all", str(db), "--out", str(tmp_path / "o"), "--workers", "1", "--device", "no-such-device",
            "--model", "diffuse+ggx", "--quiet"]
    r = subprocess.run(CLI + args, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr                  # no Dask log records, no traceback
    line = lines[0]
    assert line.startswith("brdfcl: error: cluster: fitting ") and "failed on worker tcp://" in line
    # one worker: two chunks of one material (brdfcl.app.cluster.fit_on_cluster); the first that fails is named
    assert sum(f"fitting {n} (1 material)" in line for n in NAMES) == 1
    assert "DeviceError: no OpenCL device matches 'no-such-device'" in line
    r = subprocess.run(CLI + ["--debug"] + args, capture_output=True, text=True, timeout=300)
    assert r.returncode != 0
    assert "Traceback" in r.stderr and "in pick_device" in r.stderr     # the worker's frames
    assert "WorkerError: cluster: fitting" in r.stderr
    assert r.stderr.count("Compute Failed") == 0


@pytest.mark.slow
def test_api_worker_failure(db, tmp_path):
    client = make_client(workers=1)
    try:
        with pytest.raises(WorkerError) as err:
            fit_all(db, tmp_path / "o", FitOptions(model="diffuse+ggx", device="no-such-device"), client=client)
        assert "\n" not in str(err.value) and "no-such-device" in str(err.value)
        cause = err.value.__cause__
        assert isinstance(cause, RemoteTraceback) and "DeviceError" in str(cause) and "Traceback" in str(cause)
        # the cluster is still usable: a good run afterwards fits both materials
        rep = fit_all(db, tmp_path / "o2", model="diffuse+ggx", client=client)
        assert rep.ok and sorted(r.name for r in rep.results) == NAMES
    finally:
        client.close()


def test_pyopencl_error_in_a_task_is_readable(db, monkeypatch):
    e = pyopencl_error()
    assert "_ErrorRecord" in repr(e)                   # what reached the user before
    with pytest.raises(TypeError):
        pickle.dumps(e)
    assert describe_error(e) == "pyopencl.LogicError: create_buffer failed: INVALID_BUFFER_SIZE"

    def failing_fitter(opts, **kw):
        raise e
    monkeypatch.setattr(brdfcl.optim.fit, "Fitter", failing_fitter)
    monkeypatch.setattr(brdfcl.app.cluster, "_WORKER_FITTERS", {})
    results, skipped, failure = fit_chunk([str(db / f"{n}.binary") for n in NAMES], FitOptions())
    assert results == [] and skipped == {}
    line, tb = failure
    assert "INVALID_BUFFER_SIZE" in line and "\n" not in line and "_ErrorRecord" not in line
    assert "Traceback" in tb and "failing_fitter" in tb
    pickle.loads(pickle.dumps((results, skipped, failure)))        # what the worker sends back


def test_chunk_label():
    assert brdfcl.app.cluster.chunk_label(["a/x.binary", "b/y.binary"]) == "x, y"
    assert brdfcl.app.cluster.chunk_label([f"m{i}.binary" for i in range(5)]) == "m0, m1, m2 and 2 more"


def test_describe_error_one_line():
    assert describe_error(ValueError("first\nsecond")) == "ValueError: first [...]"
    assert describe_error(brdfcl.device.platforms.DeviceError("no device 'x'; devices:\n[0] pocl")) == \
        "DeviceError: no device 'x'; devices [...]"
    assert describe_error(KeyError("k")) == "KeyError: 'k'"

    class Record:                   # an error whose text is only its record's repr: routine and code
        def routine(self):
            return "clEnqueueNDRangeKernel"

        def code(self):
            return -5
    err = RuntimeError("<pyopencl._cl._ErrorRecord object at 0x7f>")
    err.what = Record()
    assert describe_error(err) == "RuntimeError: clEnqueueNDRangeKernel failed with code -5"
