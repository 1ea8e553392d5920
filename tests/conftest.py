"""Shared fixtures.  MERL-proxy data comes from ../shared (or BRDFCL_SHARED); tests that need it
skip with a reason when it is absent.  Proxy tables are generated once into BRDFCL_PROXY_CACHE
(default ~/.cache/brdfcl/proxy), never into the repository."""
import atexit
import fcntl
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

# brdfcl's own cache (vector widths chosen by probing, generated sources, kept programs) lives in
# a folder of this test session, inherited by the CLI subprocesses, and goes with the session:
# tests neither depend on nor leave state in the user's ~/.cache/brdfcl.  A BRDFCL_CACHE_DIR set
# beforehand is used and kept (.ci/run shares one between its test runs).
if "BRDFCL_CACHE_DIR" not in os.environ:
    os.environ["BRDFCL_CACHE_DIR"] = tempfile.mkdtemp(prefix="brdfcl-test-cache-")
    atexit.register(shutil.rmtree, os.environ["BRDFCL_CACHE_DIR"], ignore_errors=True)


@pytest.fixture(scope="session", autouse=True)
def _devices_checked():
    """Every device's build check made once, first: a run that makes it says in one line which
    platform it leaves out, and a CLI test counting its lines must not depend on being first."""
    try:
        from brdfcl.device.platforms import usable
        usable()
    except Exception:                   # no pyopencl or no platform: those tests skip themselves
        pass

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("BRDFCL_SHARED", ROOT.parent / "shared"))
PROXY_CACHE = Path(os.environ.get("BRDFCL_PROXY_CACHE", Path.home() / ".cache" / "brdfcl" / "proxy"))


def proxy_files(names):
    """Paths of MERL-proxy files for the named materials, generated on first use."""
    tool = SHARED / "tools" / "merl_proxy.py"
    weights = SHARED / "data" / "nbrdf" / "merl"
    if not tool.exists() or not weights.is_dir():
        why = (f"MERL-proxy data not available: {SHARED} has no tools/merl_proxy.py "
               f"and data/nbrdf/merl (set BRDFCL_SHARED)")
        if os.environ.get("BRDFCL_REQUIRE_SHARED") == "1":
            pytest.fail(why)
        pytest.skip(why)
    PROXY_CACHE.mkdir(parents=True, exist_ok=True)
    with open(PROXY_CACHE / ".lock", "w") as lock:     # test processes running side by side (-n)
        fcntl.flock(lock, fcntl.LOCK_EX)
        missing = [n for n in names if not (PROXY_CACHE / f"{n}.binary").exists()]
        if missing:
            subprocess.run([sys.executable, str(tool), str(weights), str(PROXY_CACHE),
                            "--materials", ",".join(missing)], check=True, capture_output=True)
    return [PROXY_CACHE / f"{n}.binary" for n in names]


KRYLON = SHARED / "data" / "cornell" / "krylon_blue.brdf"


@pytest.fixture(scope="session")
def krylon():
    """The real Cornell spectral measurement (brdfcl.data.samples.Samples)."""
    from brdfcl.data.readers import read_samples
    if not KRYLON.exists():
        why = f"Cornell measurement not available: {KRYLON} is missing (set BRDFCL_SHARED)"
        if os.environ.get("BRDFCL_REQUIRE_SHARED") == "1":
            pytest.fail(why)
        pytest.skip(why)
    return read_samples(KRYLON)


@pytest.fixture(scope="session")
def proxy_pair():
    return proxy_files(["aluminium", "specular-red-phenolic"])


@pytest.fixture(scope="session")
def demo_db(tmp_path_factory):
    from brdfcl.model.synth import write_synth
    d = tmp_path_factory.mktemp("demo")
    write_synth(d, log=None)
    return d


@pytest.fixture()
def user_ndf(tmp_path, monkeypatch):
    """A user's own NDF (GGX under another name) registered from a module file in tmp_path, as a
    user's term module would be: (the module's file, the term)."""
    import dataclasses
    import types

    from brdfcl.model.terms import REGISTRY
    src = tmp_path / "my_ndf.py"
    src.write_text("# version 1\n")
    mod = types.ModuleType("my_ndf")
    mod.__file__ = str(src)
    monkeypatch.setitem(sys.modules, "my_ndf", mod)
    return src, dataclasses.replace(REGISTRY["ndf"]["ggx"], name="my_ggx", origin="my_ndf")
