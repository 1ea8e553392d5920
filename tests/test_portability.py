"""Programs that are right on the device they run on, whatever it reports about itself.

The vector width is chosen by building and self-testing (brdfcl.device.width), the choice is
cached per device, a broken PoCL kernel cache is repaired, and every PoCL build present
(pip wheel, Debian's pocl-opencl-icd) gives the same results."""
import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from brdfcl.data.merl import read_merl
from brdfcl.device import selftest, width
from brdfcl.device.engine import Engine
from brdfcl.device.errors import ProgramError
from brdfcl.device.platforms import all_devices, selector_of
from brdfcl.device.soundness import sound_bitcode, sound_elf
from brdfcl.optim.fit import FitOptions, fit_tables, select_cells
from tests.runtimes import building, device_params, is_cpu, is_pocl

POCL = device_params(is_pocl)               # PoCL's kernel cache: each PoCL build that builds here
CPU_RUNTIMES = building(is_cpu)             # every CPU runtime that builds here (PoCL builds, Intel's)


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path / "brdfcl-cache"))
    monkeypatch.delenv(width.ENV, raising=False)
    return tmp_path / "brdfcl-cache" / "vector-widths.json"


def _platform_device(selector=None):
    from brdfcl.device.platforms import pick_device
    return pick_device(selector)


def test_falls_back_to_the_widest_width_that_passes(cache):
    p, d = _platform_device()
    calls = []

    def fake_probe(selector, real, w):         # a device whose compiler targets half its width
        calls.append(w)
        if w > 4:
            return {"ok": False, "detail": "crashed (signal 11)"}
        return {"ok": True, "detail": "passed (max relative error 1e-07)"}
    top = width.candidates(d, "float")[0]
    got = width.choose(p, d, "float", probe_fn=fake_probe)
    assert got.width == min(4, top)
    assert calls == [w for w in (16, 8, 4, 2, 1) if min(4, top) <= w <= top]
    assert "crashed (signal 11)" in got.reason and f"{got.width} passed" in got.reason
    # cached per device: a second choice (a second process) probes nothing
    assert width.choose(p, d, "float", probe_fn=lambda *a: pytest.fail("probed again")).width == got.width
    entry = next(iter(json.loads(cache.read_text()).values()))
    assert entry["width"] == got.width and entry["real"] == "float"
    # another precision is another decision
    assert width.choose(p, d, "double", probe_fn=fake_probe).width == min(4, width.candidates(d, "double")[0])


def test_no_width_works_is_one_clear_error(cache):
    """Every width failing is one error that names each width tried and why (the widest one
    tried is the CPU's: 16 floats with AVX-512, 8 with AVX2)."""
    p, d = _platform_device()
    top = width.candidates(d, "float")[0]
    with pytest.raises(ProgramError, match=f"no vector width works on .*: {top} failed: exit status 1"):
        width.choose(p, d, "float", probe_fn=lambda s, r, w: {"ok": False, "detail": "exit status 1"}
                     if w == top else {"ok": False, "detail": "wrong"})


def test_override_by_argument_and_environment(cache, monkeypatch):
    p, d = _platform_device()
    assert width.choose(p, d, "float", explicit=2, probe_fn=pytest.fail).width == 2
    monkeypatch.setenv(width.ENV, "4")
    got = width.choose(p, d, "float", probe_fn=pytest.fail)
    assert got.width == 4 and width.ENV in got.reason
    monkeypatch.setenv(width.ENV, "3")
    with pytest.raises(ValueError, match="BRDFCL_VECTOR_WIDTH='3': vector width must be one of 1, 2, 4, 8, 16"):
        width.choose(p, d, "float")


def test_the_real_probe_passes_and_detects_a_crash(cache):
    p, d = _platform_device()
    res = width.probe(selector_of(p, d), "double", 2)
    assert res["ok"] and "passed" in res["detail"], res
    crash = width.run_probe([sys.executable, "-c", "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)"])
    assert not crash["ok"] and crash["detail"] == "crashed (signal 11)"
    noise = width.run_probe([sys.executable, "-c", "import sys; sys.exit('LLVM ERROR: Cannot select fma')"])
    assert not noise["ok"] and "Cannot select fma" in noise["detail"]


def test_self_test_catches_a_program_that_does_not_match_its_description():
    eng = Engine("diffuse+ggx", metric="log")
    assert eng.self_test.ok and eng.self_test.max_error < 1e-5
    wrong = Engine("diffuse+ggx", metric="log")
    wrong.opt = replace(wrong.opt, metric="l2")               # the program still computes log
    res = selftest.check(wrong)
    assert not res.ok and "relative error" in res.detail


def test_forced_narrower_width_gives_the_same_fits(demo_db):
    """A narrower width computes the same numbers (to float32 rounding: the compiler vectorises
    each width differently) and so the same fits.  A fit in a flat valley may stop at another
    point of it after different roundings: measured 1.6e-5 relative in loss on synth-fabric."""
    tables = [read_merl(demo_db / f"{n}.binary") for n in ("synth-smooth-metal", "synth-fabric")]
    evaluated = {}
    for w in (16, 2):
        eng = Engine("diffuse+diffraction+ggx", vector_width=w)
        m = eng.model
        x = m.search_x_lo + np.random.default_rng(0).random((12, m.n_free)) * (m.search_x_hi - m.search_x_lo)
        evaluated[w] = eng.grad(eng.cellset(tables, select_cells(None)), m.from_x(x), np.arange(12) % 2)
    for a, b in zip(evaluated[16], evaluated[2]):
        np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-6 * np.abs(a).max())
    base = fit_tables(tables, FitOptions(model="diffuse+diffraction+ggx"))
    narrow = fit_tables(tables, FitOptions(model="diffuse+diffraction+ggx", vector_width=2))
    for a, b in zip(base, narrow):
        assert a.success and b.success
        assert b.loss == pytest.approx(a.loss, rel=1e-4, abs=1e-12), (a.name, a.loss, b.loss)


def test_sound_file_checks(tmp_path):
    assert not sound_elf(tmp_path / "missing.so")
    so = tmp_path / "k.so"
    so.write_bytes(b"\x7fELF" + b"\0" * 100)
    assert not sound_elf(so)
    libs = [p for p in (os.path.dirname(np.__file__) + "/_core",) for p in __import__("glob").glob(p + "/*.so")]
    lib = open(libs[0], "rb").read()
    so.write_bytes(lib)
    assert sound_elf(so)
    so.write_bytes(lib[: len(lib) // 2])
    assert not sound_elf(so)
    bc = tmp_path / "program.bc"
    bc.write_bytes(b"BC\xc0\xde")
    assert not sound_bitcode(bc)


def test_the_cache_check_reads_only_new_or_changed_files(tmp_path, monkeypatch):
    """A file found sound is remembered by size and time: the next run does not read it again,
    a changed one is read, a broken one removed with its entry."""
    from brdfcl.device import poclcache
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path / "brdfcl"))
    root = tmp_path / "pocl"
    monkeypatch.setattr(poclcache, "pocl_cache_dir", lambda platform: root)
    lib = open(__import__("glob").glob(os.path.dirname(np.__file__) + "/**/*.so", recursive=True)[0], "rb").read()
    for e in ("e1", "e2"):
        (root / "ab" / e / "kern" / "wg").mkdir(parents=True)
        (root / "ab" / e / "kern" / "wg" / "k.so").write_bytes(lib)
    reads = []
    real = poclcache.sound
    monkeypatch.setattr(poclcache, "sound", lambda p: reads.append(p) or real(p))

    def repair():
        poclcache._REPAIRED.discard(root)
        return poclcache.repair_pocl_cache(None)
    assert repair() == [] and len(reads) == 2
    assert repair() == [] and len(reads) == 2                       # nothing read again
    e1, e2 = (root / "ab" / e / "kern" / "wg" / "k.so" for e in ("e1", "e2"))
    st = e1.stat()
    e1.write_bytes(lib[:-8] + b"\0" * 8)                            # damaged in place, times put back:
    os.utime(e1, ns=(st.st_atime_ns, st.st_mtime_ns))                # only the change time tells
    e2.write_bytes(lib[: len(lib) // 2])
    assert sorted(repair()) == [str(root / "ab" / "e2")] and len(reads) == 4   # both read again
    assert (root / "ab" / "e1").is_dir() and not (root / "ab" / "e2").exists()
    prints = json.loads((tmp_path / "brdfcl" / "pocl-fingerprints.json").read_text())
    prints[str(e1)] = "not a print"                                  # a damaged print file: no crash
    (tmp_path / "brdfcl" / "pocl-fingerprints.json").write_text(json.dumps(prints))
    assert repair() == [] and len(reads) == 5


CORRUPT = {
    "truncated program": lambda d: [p.write_bytes(p.read_bytes()[:100]) for p in d.rglob("program.bc")],
    "empty program": lambda d: [p.write_bytes(b"") for p in d.rglob("program.bc")],
    "truncated kernels": lambda d: [p.write_bytes(p.read_bytes()[:1000]) for p in d.rglob("*.so")],
    "garbage kernels": lambda d: [p.write_bytes(os.urandom(4096)) for p in d.rglob("*.so")],
}
RUN = ("import numpy as np; from brdfcl.device.engine import Engine; from brdfcl.device.engine import select_cells; "
       "e = Engine('diffuse+ggx'); idx = select_cells()[::97]; "
       "cs = e.upload(['m'], idx, np.full((1, 3, idx.size), 0.1, np.float32)); "
       "print(e.loss(cs, e.model.defaults(), [0])[0], e.self_test.ok)")


def _runner(tmp_path, device):
    """RUN in a fresh process with its own PoCL and brdfcl caches under tmp_path."""
    env = dict(os.environ, POCL_CACHE_DIR=str(tmp_path / "pocl"), BRDFCL_DEVICE=device,
               BRDFCL_CACHE_DIR=str(tmp_path / "brdfcl"))
    return lambda: subprocess.run([sys.executable, "-c", RUN], capture_output=True, text=True, env=env, timeout=600)


@pytest.mark.slow
@pytest.mark.parametrize("device", POCL)
@pytest.mark.parametrize("damage", list(CORRUPT))
def test_a_broken_pocl_cache_does_not_break_the_next_run(tmp_path, device, damage):
    run = _runner(tmp_path, device)
    first = run()
    assert first.returncode == 0, first.stderr[-2000:]
    assert list((tmp_path / "pocl").rglob("*.so")), "PoCL wrote no kernel cache here"
    CORRUPT[damage](tmp_path / "pocl")
    again = run()
    assert again.returncode == 0, again.stderr[-2000:]
    assert again.stdout == first.stdout
    assert again.stderr.count("removed a broken PoCL kernel-cache entr") == 1      # one line
    assert run().stderr.count("removed") == 0                 # repaired for good


def _scramble_middle(d):
    """Damage that keeps every file's length: no structural check can see it, PoCL aborts on it."""
    for p in d.rglob("program.bc"):
        data = bytearray(p.read_bytes())
        mid = len(data) // 2
        data[mid:mid + 2000] = os.urandom(min(2000, len(data) - mid))
        p.write_bytes(bytes(data))


@pytest.mark.slow
@pytest.mark.parametrize("device", POCL)
def test_damage_inside_a_cache_file_is_seen_by_its_fingerprint(tmp_path, device):
    run = _runner(tmp_path, device)
    first = run()
    assert first.returncode == 0, first.stderr[-2000:]
    _scramble_middle(tmp_path / "pocl")
    again = run()                       # without the fingerprint, LLVM aborts on this entry
    assert again.returncode == 0, again.stderr[-2000:]
    assert again.stdout == first.stdout
    assert again.stderr.count("removed a broken PoCL kernel-cache entr") == 1
    assert run().stderr.count("brdfcl:") == 0


def test_a_run_that_died_building_moves_the_program_to_a_new_cache_key(tmp_path, monkeypatch):
    """PoCL can abort the whole process while building; the next run sees the dead run's marker."""
    from brdfcl.device import crashguard
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    dev = type("Dev", (), {"name": "cpu", "driver_version": "1"})()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    with crashguard.crash_guard("src", dev) as attempt:
        assert attempt == 0
        marker = next((tmp_path / "building").iterdir())
        marker.rename(marker.with_suffix("." + dead.stdout.strip()))     # as if that run had died here
    lines = []
    with crashguard.crash_guard("src", dev, log=lines.append) as attempt:
        assert attempt == 1
    assert len(lines) == 1 and "a run died building or testing this program on cpu" in lines[0]
    with crashguard.crash_guard("src", dev, log=lines.append) as attempt:
        assert attempt == 1                                           # kept for good
    assert len(lines) == 1


@pytest.mark.skipif(len(CPU_RUNTIMES) < 2, reason="only one CPU runtime builds here (apt-get install "
                    "pocl-opencl-icd adds Debian's PoCL, pip install '.[intel-cpu]' Intel's)")
def test_every_cpu_runtime_gives_the_same_fit(demo_db):
    (table,) = [read_merl(demo_db / "synth-smooth-metal.binary")]
    losses = {}
    for dev in CPU_RUNTIMES:
        (res,) = fit_tables([table], FitOptions(model="diffuse+diffraction+ggx", device=dev))
        losses[dev] = res.loss
        assert res.success
    ref = losses[CPU_RUNTIMES[0]]
    assert all(v == pytest.approx(ref, rel=1e-5, abs=1e-12) for v in losses.values()), losses


def test_the_default_is_the_first_device_that_builds_in_order():
    from brdfcl.device import platforms
    devs = all_devices()
    order = platforms.preference(devs)
    building = [i for i in order if platforms.check(i, devs).ok]
    if not building:
        pytest.skip("no device builds here")
    p, d = platforms.pick_device(None)
    assert (p.int_ptr, d.int_ptr) == (devs[building[0]][0].int_ptr, devs[building[0]][1].int_ptr)
    ranks = [(not platforms.has_fp64(d), 0 if platforms.is_pocl(p) else 1 if "intel" in p.name.lower() else 2,
              [-v for v in platforms.pocl_version(p)]) for p, d in (devs[i] for i in order)]
    assert ranks == sorted(ranks)            # float64 first; PoCL, newest first, then Intel's, then any


@pytest.mark.slow
def test_info_shows_status_width_reason_and_self_test():
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "info"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    lines = [ln.strip() for ln in r.stdout.splitlines()]
    float_lines = [ln for ln in lines if ln.startswith("float: vector width")]
    status = [ln for ln in lines if ln.startswith("status: ")]
    assert len(status) == len(all_devices()) and sum(ln.endswith("; chosen") for ln in status) == 1, status
    assert len(float_lines) == sum(ln.startswith("status: builds") for ln in status)
    assert all("self-test passed" in ln and "(" in ln for ln in float_lines), float_lines
    assert lines[-1].startswith("default device: ")
    assert max(map(len, r.stdout.splitlines() + r.stderr.splitlines())) <= 200


def test_the_kernel_hash_follows_every_term_module(user_ndf, monkeypatch):
    """Cached decisions about compiled programs (vector widths) are keyed by a hash of what the
    kernels are made from, a user's own term module included, without generating any C."""
    from brdfcl.kernels import codegen
    from brdfcl.model.terms import REGISTRY
    src, mine = user_ndf
    codegen.kernel_sources_hash.cache_clear()
    before = codegen.kernel_sources_hash()
    monkeypatch.setitem(REGISTRY["ndf"], "my_ggx", mine)
    try:
        codegen.kernel_sources_hash.cache_clear()
        registered = codegen.kernel_sources_hash()
        src.write_text("# version 2\n")
        codegen.kernel_sources_hash.cache_clear()
        edited = codegen.kernel_sources_hash()
    finally:
        codegen.kernel_sources_hash.cache_clear()
    assert len({before, registered, edited}) == 3
