"""Any x86-64 CPU: a runtime pip installed made loadable, a platform that cannot build left out
with one line saying why, every build error one short line with its log in a file.

The path where the first platform cannot build is tested for real where the pip PoCL's LLVM
does not know the CPU, and everywhere by ``BRDFCL_BREAK_PLATFORM`` (the check's one-line kernel
then carries an ``#error``, so the compiler itself fails)."""
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from brdfcl.device import buildcheck, buildlog, cpu, runtimes, width
from brdfcl.device.platforms import all_devices, check, pick_device, preference, short_name
from tests.runtimes import building

LONGEST = 200
# The pip PoCL's text for one failed build (pyopencl puts the log into the error, PoCL repeats it)
POCL_FAILURE = ("clBuildProgram failed: BUILD_PROGRAM_FAILURE - clBuildProgram failed: BUILD_PROGRAM_FAILURE\n\n"
                "Build on <pyopencl.Device 'pthread-AMD EPYC' on 'Portable Computing Language' at 0x5652>:\n\n"
                "error: unknown target CPU 'generic'\nDevice pthread-AMD EPYC failed to build the program\n\n"
                "(options: -cl-mad-enable -I /venv/lib/python3.11/site-packages/pyopencl/cl)\n") * 3


class _Platform:
    name = "Portable Computing Language"
    version = "OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC, LLVM 14.0.6, SLEEF, DISTRO, POCL_DEBUG"


def _run(args, env=None, timeout=900):
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, **(env or {})))


def _lines(r):
    return r.stdout.splitlines() + r.stderr.splitlines()


def test_a_build_failure_is_its_first_compiler_error():
    assert buildlog.cause(POCL_FAILURE) == "error: unknown target CPU 'generic'"
    assert buildcheck.explain(_Platform, buildlog.cause(POCL_FAILURE)) == \
        "its LLVM 14 does not know this CPU (generic)"
    assert buildcheck.label(_Platform) == "PoCL 3.0-rc2"
    assert len(buildlog.cause("error: " + "x" * 500)) == buildlog.CAUSE_CHARS
    assert buildlog.cause("") == "no build log"
    assert buildlog.cause("<kernel>:3:5: error: use of undeclared identifier 'q'\n") == \
        "error: use of undeclared identifier 'q'"


def test_the_full_log_is_kept_in_a_file(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    path = buildlog.keep(POCL_FAILURE, "one-line kernel on a CPU")
    assert path.parent == tmp_path / "build-logs" and POCL_FAILURE in path.read_text()


def test_the_check_is_cached_per_device(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(buildcheck, "_CHECKED", {})
    p, d = all_devices()[0]
    calls = []

    def child(selector, key):
        calls.append(selector)
        return buildcheck.Check(False, "error: unknown target CPU 'generic'", None), True
    got = buildcheck.check(_Platform, d, "0:0", run=child)
    assert not got.ok and got.reason == "its LLVM 14 does not know this CPU (generic)" and calls == ["0:0"]
    monkeypatch.setattr(buildcheck, "_CHECKED", {})           # a second process: read from the file
    assert buildcheck.check(_Platform, d, "0:0", run=pytest.fail) == got
    monkeypatch.setattr(buildcheck, "_CHECKED", {})           # a crash is not the compiler's answer:
    monkeypatch.setenv(buildcheck.BREAK_ENV, "another key")   # not kept, checked again next time
    crash = buildcheck.check(_Platform, d, "0:0", run=lambda s, k: (buildcheck.Check(False, "crashed"), False))
    monkeypatch.setattr(buildcheck, "_CHECKED", {})
    assert not crash.ok and buildcheck.check(_Platform, d, "0:0", run=lambda s, k: (buildcheck.Check(True), True)).ok


def test_a_cpu_device_is_probed_from_the_width_of_the_cpu_not_its_report():
    import pyopencl as cl

    class IntelLike:                        # Intel's runtime reports one float on AVX-512
        type = cl.device_type.CPU
        preferred_vector_width_float = preferred_vector_width_double = 1
    top = cpu.native_width("float")
    assert width.candidates(IntelLike, "float") == [w for w in (16, 8, 4, 2, 1) if w <= top]
    assert width.candidates(IntelLike, "double")[0] == cpu.native_width("double")


def test_the_vendors_folder_holds_the_system_icds_and_the_runtime(tmp_path, monkeypatch):
    system = tmp_path / "etc"
    system.mkdir()
    (system / "pocl.icd").write_text("libpocl.so.2\n")
    monkeypatch.setattr(runtimes, "SYSTEM_VENDORS", system)
    rt = runtimes.Runtime("Intel(R) OpenCL", "1", tmp_path / "lib" / "libintelocl.so", ())
    folder = runtimes.vendors_folder([rt], tmp_path / "cache")
    assert sorted(f.name for f in folder.iterdir()) == ["brdfcl-libintelocl.icd", "pocl.icd"]
    assert (folder / "brdfcl-libintelocl.icd").read_text().strip() == str(rt.library)
    assert runtimes.vendors_folder([rt], tmp_path / "cache") == folder       # written once
    (system / "nvidia.icd").write_text("libnvidia-opencl.so.1\n")           # the system changed
    assert runtimes.vendors_folder([rt], tmp_path / "cache") != folder


INTEL = runtimes.intel_cpu_runtime()
needs_intel = pytest.mark.skipif(INTEL is None, reason="Intel's CPU runtime is not installed "
                                                       "(pip install '.[intel-cpu]')")


@needs_intel
def test_intels_runtime_is_listed_in_every_process_without_environment_variables():
    env = {k: v for k, v in os.environ.items() if k not in (runtimes.VENDORS_ENV, runtimes.OURS_ENV,
                                                              "LD_LIBRARY_PATH")}
    code = "from brdfcl.device.platforms import all_devices; print([p.name for p, d in all_devices()])"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and "Intel(R) OpenCL" in r.stdout, r.stderr[-2000:]


@needs_intel
def test_a_users_own_icd_folder_is_left_as_it_is(tmp_path):
    code = "from brdfcl.device.platforms import all_devices; print([p.name for p, d in all_devices()])"
    r = _run(["-c", code + "; from brdfcl.device.runtimes import not_loaded; print(not_loaded())"],
             {runtimes.VENDORS_ENV: str(tmp_path)})
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Intel(R) OpenCL" not in r.stdout and f"{runtimes.VENDORS_ENV} is set" in r.stdout, r.stdout


def _first_choice():
    devs = all_devices()
    order = [i for i in preference(devs) if check(i, devs).ok]
    return devs, order


@pytest.mark.slow
def test_a_platform_that_cannot_build_is_left_out_with_one_line(tmp_path):
    """The default platform's check made to fail: the next device that builds is used, one line
    says which and why, and nothing else changes."""
    devs, order = _first_choice()
    if len(order) < 2:
        pytest.skip("one device builds here: nothing to fall back to")
    broken, then = devs[order[0]][0], devs[order[1]]
    want = buildcheck.label(broken) if "PoCL" in buildcheck.label(broken) else broken.name
    env = {buildcheck.BREAK_ENV: want, "BRDFCL_CACHE_DIR": str(tmp_path)}
    code = ("import numpy as np; from brdfcl.device.engine import Engine, select_cells; e = Engine('diffuse+ggx'); "
            "idx = select_cells()[::97]; cs = e.upload(['m'], idx, np.full((1, 3, idx.size), 0.1, np.float32)); "
            "print(e.platform.name, '|', e.device.name, e.self_test.ok)")
    r = _run(["-c", code], env)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == f"{then[0].name} | {then[1].name} True"
    notes = [ln for ln in r.stderr.splitlines() if ln.startswith("brdfcl: ")]
    assert len(notes) == 1, r.stderr
    assert notes[0].startswith(f"brdfcl: {buildcheck.label(broken)}: error: injected build failure; ")
    assert notes[0].endswith(f"; using {buildcheck.label(then[0])} ({then[1].name})") and len(notes[0]) <= LONGEST
    info = _run(["-m", "brdfcl.app.cli", "info"], env)
    assert info.returncode == 0, info.stderr
    assert "status: cannot build a program: error: injected build failure" in info.stdout
    chosen = [ln.strip() for ln in info.stdout.splitlines() if ln.strip().startswith("status: ")]
    index = next(i for i, (p, d) in enumerate(devs) if p.int_ptr == then[0].int_ptr and d.int_ptr == then[1].int_ptr)
    assert chosen[index] == "status: builds programs; chosen", chosen
    assert sum(ln.endswith("; chosen") for ln in chosen) == 1
    assert max(map(len, _lines(info))) <= LONGEST


@pytest.mark.slow
def test_no_device_that_builds_is_one_line_with_what_to_install(tmp_path, demo_db):
    env = {buildcheck.BREAK_ENV: "opencl", "BRDFCL_CACHE_DIR": str(tmp_path)}      # every platform
    r = _run(["-m", "brdfcl.app.cli", "fit-all", str(demo_db), "--out", str(tmp_path / "out"),
              "--model", "diffuse+ggx"], env)
    assert r.returncode == 2
    err = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("brdfcl: error: no OpenCL device builds here"), err
    assert err[0].endswith(f"to get one: {runtimes.install_hint()}") and len(err[0]) <= LONGEST, err[0]
    info = _run(["-m", "brdfcl.app.cli", "info"], env)
    assert info.returncode == 1 and info.stdout.splitlines()[-1].startswith("no device: ")
    assert max(map(len, _lines(info))) <= LONGEST


def test_a_program_that_fails_to_build_is_one_line_naming_model_device_and_log(monkeypatch, tmp_path):
    """However long the compiler's error, the line keeps the model, the device and the log's path."""
    from brdfcl.device import engine
    from brdfcl.device.errors import ProgramError
    short = tempfile.mkdtemp(prefix="brdfcl-cache-")         # about as long as ~/.cache/brdfcl
    monkeypatch.setenv("BRDFCL_CACHE_DIR", short)
    broken = "#error this kernel is broken " + "because " * 40 + "\n"
    monkeypatch.setattr(engine, "render", lambda model, opt: broken + "int x;\n" * 500)
    with pytest.raises(ProgramError) as e:
        engine.Engine("diffuse+diffraction+ggx", vector_width=16)
    msg = str(e.value)
    assert "\n" not in msg and len(msg) <= LONGEST, msg
    assert msg.startswith("diffuse+diffraction") and "error: this kernel" in msg
    assert short_name(pick_device()[1]) in msg
    try:
        log = Path(msg.rsplit("(build log: ", 1)[1].rstrip(")")).expanduser()
        assert "this kernel is broken because because" in log.read_text()
    finally:
        shutil.rmtree(short)


@pytest.mark.skipif(not building(), reason="no device builds here")
def test_a_fit_error_on_the_command_line_is_short_without_debug(tmp_path, demo_db):
    r = _run(["-m", "brdfcl.app.cli", "fit-all", str(demo_db), "--out", str(tmp_path), "--device", "no-such"])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert max(map(len, _lines(r))) <= LONGEST


@needs_intel
@pytest.mark.slow
def test_dask_workers_load_intels_runtime_themselves(tmp_path):
    """A cluster started before any device is listed: its workers inherit no ICD folder and must
    make Intel's runtime loadable themselves."""
    pytest.importorskip("distributed")
    env = {k: v for k, v in os.environ.items() if k not in (runtimes.VENDORS_ENV, runtimes.OURS_ENV)}
    code = """
import os
from brdfcl.app.cluster import make_client

def names():
    from brdfcl.device.platforms import all_devices
    return sorted({p.name for p, d in all_devices()}), os.environ.get("BRDFCL_ICD_VENDORS")

if __name__ == "__main__":
    assert "BRDFCL_ICD_VENDORS" not in os.environ
    with make_client(workers=1) as client:
        print(list(client.run(names).values()))
"""
    (tmp_path / "workers.py").write_text(code)
    r = subprocess.run([sys.executable, str(tmp_path / "workers.py")], capture_output=True, text=True, env=env,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Intel(R) OpenCL" in r.stdout, r.stdout
