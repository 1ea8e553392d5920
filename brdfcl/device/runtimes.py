"""OpenCL CPU runtimes that pip installed, made loadable before the first platform listing.

The pip wheel's PoCL is found by pyopencl's own ICD loader.  Intel's OpenCL CPU runtime
(``intel-opencl-rt``, the ``intel-cpu`` extra) is not: its wheel installs an ICD file naming a
placeholder path, and ``libintelocl.so`` needs the compiler runtime of ``intel-cmplr-lib-rt``
(``libimf.so``, ``libsvml.so``, ``libintlc.so.5``, ``libirng.so``), which the dynamic loader
does not look for where pip put them.  `prepare` makes it loadable in this process and in the
processes it starts (probes, Dask workers): it loads those libraries first (a library already
loaded satisfies a later dependency on its name, so no ``LD_LIBRARY_PATH`` is needed), and
points the ICD loader (``OCL_ICD_VENDORS``) at a folder of brdfcl's cache that holds the
system's ICD files (``/etc/OpenCL/vendors``) and one naming the installed runtime.

A user's own ``OCL_ICD_VENDORS`` is left as it is.  Nothing here is needed where Intel's
runtime is not installed; `prepare` then changes nothing.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

SYSTEM_VENDORS = Path("/etc/OpenCL/vendors")
VENDORS_ENV = "OCL_ICD_VENDORS"
OURS_ENV = "BRDFCL_ICD_VENDORS"             # the folder prepare made (so a child knows it is ours)
DISTRIBUTION = "intel-opencl-rt"
LIBRARY = "libintelocl.so"
# libintelocl.so's dependencies in intel-cmplr-lib-rt, each after the ones it needs itself
DEPENDENCIES = ("libintlc.so.5", "libirng.so", "libimf.so", "libsvml.so")
INSTALL_HINT = "pip install 'brdfcl[intel-cpu]' or apt install pocl-opencl-icd"

_PREPARED: list = []


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
    cmplr = _dist_files("intel-cmplr-lib-rt")
    if cmplr is not None:
        folders += sorted({f.parent for f in cmplr[1]} - {lib.parent})
    preload = []
    for dep in DEPENDENCIES:
        path = next((d / dep for d in folders if (d / dep).is_file()), None)
        if path is not None:
            preload.append(path)
    return Runtime("Intel(R) OpenCL", version, lib, tuple(preload))


def _named_by_system(lib: Path) -> bool:
    """True when an ICD file of the system already names this library (nothing to add)."""
    try:
        icds = list(SYSTEM_VENDORS.glob("*.icd"))
    except OSError:
        return False
    for icd in icds:
        try:
            text = icd.read_text().strip()
        except OSError:
            continue
        if text and Path(text).is_absolute() and Path(text).resolve() == lib:
            return True
    return False


def vendors_folder(runtimes, base: Path) -> Path:
    """A folder of ICD files: the system's and one per runtime, written once per content (its
    name is a hash of it, so processes that start together share it without a race)."""
    entries = {}
    try:
        for icd in sorted(SYSTEM_VENDORS.glob("*.icd")):
            try:
                entries[icd.name] = icd.read_text()
            except OSError:
                continue
    except OSError:
        pass
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


def prepare(base: Path | None = None) -> list:
    """Make the pip-installed runtimes loadable (see the module docstring); once per process,
    before pyopencl first lists platforms.  Returns the runtimes added."""
    if _PREPARED:
        return _PREPARED[0]
    added: list = []
    _PREPARED.append(added)
    rt = intel_cpu_runtime()
    if rt is None or _named_by_system(rt.library):
        return added
    user = os.environ.get(VENDORS_ENV)
    if user and user != os.environ.get(OURS_ENV):
        return added                     # the user's choice of ICDs
    try:
        for lib in rt.preload:
            ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
    except OSError:
        return added                     # its libraries do not load here: leave it out
    if not user:
        if base is None:
            from brdfcl.device.cache import cache_dir
            base = cache_dir()
        try:
            folder = vendors_folder([rt], base)
        except OSError:
            folder = vendors_folder([rt], Path(tempfile.gettempdir()) / f"brdfcl-{os.getuid()}")
        os.environ[VENDORS_ENV] = os.environ[OURS_ENV] = str(folder)
    added.append(rt)
    return added
