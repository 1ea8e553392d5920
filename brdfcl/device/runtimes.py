"""OpenCL CPU runtimes that pip installed, made loadable before the first platform listing.

The pip wheel's PoCL is found by pyopencl's own ICD loader.  Intel's OpenCL CPU runtime
(``intel-opencl-rt``, the ``intel-cpu`` extra) is not: its wheel installs an ICD file naming a
placeholder path.  `prepare` makes it loadable in this process and in the processes it starts
(probes, Dask workers on this machine; a worker elsewhere calls it itself): it points the ICD
loader (``OCL_ICD_VENDORS``) at a folder of brdfcl's cache holding the ICD files the loader would
read (the system's ``/etc/OpenCL/vendors`` and the environment's ``PREFIX/etc/OpenCL/vendors``)
and one naming the installed library, and it loads the runtime's dependencies first
(``intel-cmplr-lib-rt``'s ``libimf.so``, ``libsvml.so``, ... and ``tbb``'s ``libtbb.so.12``) from
wherever pip put them, so that no ``LD_LIBRARY_PATH`` is needed even where they are not beside
``libintelocl.so``.

A user's own ``OCL_ICD_VENDORS`` is left as it is (`not_loaded` then says why Intel's runtime is
not listed).  Where Intel's runtime is not installed, `prepare` changes nothing.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

SYSTEM_VENDORS = Path("/etc/OpenCL/vendors")
PREFIX_VENDORS = Path(sys.prefix) / "etc" / "OpenCL" / "vendors"   # conda's ocl-icd reads these
VENDORS_ENV = "OCL_ICD_VENDORS"
OURS_ENV = "BRDFCL_ICD_VENDORS"             # the folder prepare made (so a child knows it is ours)
DISTRIBUTION = "intel-opencl-rt"
LIBRARY = "libintelocl.so"
# libintelocl.so's dependencies (intel-cmplr-lib-rt, tbb), each after the ones it needs itself
DEPENDENCIES = ("libtbb.so.12", "libintlc.so.5", "libirng.so", "libimf.so", "libsvml.so")
DEPENDENCY_DISTRIBUTIONS = ("intel-cmplr-lib-rt", "tbb")
INSTALL_HINT = "pip install 'brdfcl[intel-cpu]' (or apt install pocl-opencl-icd)"

_PREPARED: list = []
_NOT_LOADED: list = []


@dataclass(frozen=True)
class Runtime:
    """An installed OpenCL runtime: its ICD library and the libraries to load before it."""
    name: str
    version: str
    library: Path
    preload: tuple


def _dist_files(name):
    """(version, [absolute file paths]) of an installed distribution, or None."""
    from importlib import metadata
    try:
        dist = metadata.distribution(name)
    except metadata.PackageNotFoundError:
        return None
    files = [Path(str(dist.locate_file(f))).resolve() for f in (dist.files or [])]
    return dist.version, files


def intel_cpu_runtime() -> Runtime | None:
    """Intel's OpenCL CPU runtime installed by pip (x86-64 Linux only), or None."""
    if platform.system() != "Linux" or platform.machine() not in ("x86_64", "AMD64"):
        return None
    found = _dist_files(DISTRIBUTION)
    if found is None:
        return None
    version, files = found
    lib = next((f for f in files if f.name == LIBRARY and f.is_file()), None)
    if lib is None:
        return None
    folders = [lib.parent]
    for name in DEPENDENCY_DISTRIBUTIONS:
        found = _dist_files(name)
        if found is not None:
            folders += sorted({f.parent for f in found[1]} - set(folders))
    preload = []
    for dep in DEPENDENCIES:
        path = next((d / dep for d in folders if (d / dep).is_file()), None)
        if path is not None:
            preload.append(path)
    return Runtime("Intel(R) OpenCL", version, lib, tuple(preload))


def _icds():
    """{file name: text} of the ICD files the loader reads without OCL_ICD_VENDORS: the system's,
    then the environment's (each only where the library it names can be there: the Intel wheel's
    own file names a placeholder path)."""
    out: dict = {}
    for folder in (SYSTEM_VENDORS, PREFIX_VENDORS):
        try:
            files = sorted(folder.glob("*.icd"))
        except OSError:
            continue
        for icd in files:
            try:
                text = icd.read_text().strip()
            except OSError:
                continue
            if text and (not Path(text).is_absolute() or Path(text).exists()):
                out.setdefault(icd.name, text + "\n")
    return out


def _names(icds: dict, lib: Path) -> bool:
    """True when an ICD file already names this library (nothing to add)."""
    return any(Path(t.strip()).is_absolute() and Path(t.strip()).resolve() == lib for t in icds.values())


def vendors_folder(runtimes, base: Path, icds: dict | None = None) -> Path:
    """A folder of ICD files: ``icds`` (default: the loader's own, `_icds`) and one per runtime,
    written once per content (its name is a hash of it, so processes that start together share
    it without a race)."""
    entries = dict(_icds() if icds is None else icds)
    for rt in runtimes:
        entries[f"brdfcl-{rt.library.stem}.icd"] = f"{rt.library}\n"
    digest = hashlib.sha1(repr(sorted(entries.items())).encode()).hexdigest()[:16]
    folder = base / "opencl-vendors" / digest
    if folder.is_dir():
        return folder
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{digest}.", dir=folder.parent))
    for name, text in entries.items():
        (tmp / name).write_text(text)
    try:
        os.rename(tmp, folder)
    except OSError:                      # another process made it first
        shutil.rmtree(tmp, ignore_errors=True)
    return folder


def not_loaded() -> str:
    """Why an installed Intel runtime was not made loadable ("" when it was, or is not installed)."""
    prepare()
    return _NOT_LOADED[0] if _NOT_LOADED else ""


def install_hint() -> str:
    """What to do where no device builds, for this machine."""
    why = not_loaded()
    if why:
        return why
    if intel_cpu_runtime() is None and platform.system() == "Linux" and platform.machine() == "x86_64":
        return INSTALL_HINT
    return "install an OpenCL CPU runtime (e.g. apt install pocl-opencl-icd)"


def prepare(base: Path | None = None) -> list:
    """Make the pip-installed runtimes loadable (see the module docstring); once per process,
    before pyopencl first lists platforms.  Returns the runtimes added."""
    if _PREPARED:
        return _PREPARED[0]
    added: list = []
    _PREPARED.append(added)
    rt = intel_cpu_runtime()
    if rt is None:
        return added
    user = os.environ.get(VENDORS_ENV)
    if user and user != os.environ.get(OURS_ENV):
        _NOT_LOADED.append(f"Intel's runtime is installed, but {VENDORS_ENV} is set (brdfcl leaves the ICDs "
                           f"it names): add {rt.library} there or unset it")
        return added
    try:
        for lib in rt.preload:
            ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
    except OSError as e:
        _NOT_LOADED.append(f"Intel's runtime is installed, but its libraries do not load: {str(e)[:80]}")
        return added
    if not user:
        icds = _icds()
        if _names(icds, rt.library):
            return added                 # the system's ICDs already name it
        if base is None:
            from brdfcl._cache import cache_dir
            base = cache_dir()
        try:
            folder = vendors_folder([rt], base, icds)
        except OSError:                  # no writable cache: a private folder of this process
            try:
                folder = vendors_folder([rt], Path(tempfile.mkdtemp(prefix="brdfcl-icd-")), icds)
            except OSError as e:
                _NOT_LOADED.append(f"Intel's runtime is installed, but no folder for its ICD can be written: {e}")
                return added
        os.environ[VENDORS_ENV] = os.environ[OURS_ENV] = str(folder)
    added.append(rt)
    return added
