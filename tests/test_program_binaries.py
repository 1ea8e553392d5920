"""Program binaries kept in brdfcl's cache (brdfcl.device.binaries): a program that passed its
self-test is loaded from its binary by the next process, passes the same self-test, and a binary
that does not load is removed and the program built from source again."""
import pytest

from brdfcl.device import engine as engine_module
from brdfcl.device import selftest
from brdfcl.device.binaries import binary_path, load_binary
from brdfcl.device.engine import Engine

SPEC = "diffuse+ggx:smith:schlick"


@pytest.fixture()
def engine(tmp_path, monkeypatch):
    """A program built in this test, its binary kept in a cache of its own (in a shared cache, other
    programs built beside it may push it out of the newest KEEP_BINARIES)."""
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(engine_module, "_PROGRAMS", {})
    try:
        return Engine(SPEC)
    except Exception as e:          # noqa: BLE001 - no device builds here
        pytest.skip(f"no OpenCL device builds {SPEC}: {e}")


def test_a_built_program_is_kept_and_loads_from_its_binary(engine):
    path = binary_path(engine.device, engine.source)
    assert path.is_file() and path.stat().st_size > 0
    program, kernels = load_binary(engine.ctx, engine.device, engine.source, names=engine.kernel_names)
    engine.program, engine._kernels = program, kernels
    assert selftest.check(engine).ok


def test_a_binary_that_does_not_load_is_removed(engine):
    path = binary_path(engine.device, engine.source, attempt=7)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"not a program binary")
    assert load_binary(engine.ctx, engine.device, engine.source, attempt=7) is None
    assert not path.exists()
