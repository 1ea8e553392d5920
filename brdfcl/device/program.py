"""Building a generated OpenCL program so that a broken kernel cache cannot break a run.

PoCL keeps compiled programs in a cache (``POCL_CACHE_DIR``, default
``~/.cache/pocl``).  A process that crashed while compiling can leave entries
behind that make every later run fail: a truncated ``program.bc`` (the kernels
are then missing: ``INVALID_KERNEL_NAME``) or a truncated kernel library
(PoCL aborts the whole process when it cannot load it), or a file damaged in
place, which only its content shows (LLVM then aborts: "Invalid abbrev number").
So, before the first build of a process, cache entries with an incomplete file,
or with a file that differs from the fingerprint brdfcl took when that entry
last worked, are removed from PoCL's cache (they are recompiled on demand; a file
unchanged in size and times since it was last found sound is not read again), and
a program whose kernels are missing, or that fails the caller's check, is built
again under a different cache key.
"""
from __future__ import annotations

import gc
import hashlib
import os
import shutil
import struct
import warnings
from contextlib import contextmanager
from pathlib import Path

import pyopencl as cl

from brdfcl._cache import cache_dir, read_json, update_json, write_json
from brdfcl.device import buildlog
from brdfcl.device.errors import ProgramError

KERNELS = ("target", "loss", "grad", "jtj", "errors", "predict")
BUILD_OPTIONS = ["-cl-mad-enable"]
ABI_WARNING = "changes the ABI"     # LLVM, when vector arguments are wider than the target
_REPAIRED: set = set()


def pocl_cache_dir(platform) -> Path | None:
    """PoCL's kernel cache for a PoCL platform (None for other platforms)."""
    if "portable computing" not in platform.name.lower():
        return None
    base = os.environ.get("POCL_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "pocl")
    return Path(base) / "kcache" if (Path(base) / "kcache").is_dir() else Path(base)


def sound_elf(path: Path) -> bool:
    """True when a file is a complete 64- or 32-bit ELF object: magic, and every header table
    inside the file (a truncated or overwritten library fails this)."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            head = f.read(64)
    except OSError:
        return False
    if len(head) < 52 or head[:4] != b"\x7fELF" or head[4] not in (1, 2) or head[5] not in (1, 2):
        return False
    end = "<" if head[5] == 1 else ">"
    if head[4] == 2:
        if len(head) < 64:
            return False
        phoff, shoff = struct.unpack_from(end + "QQ", head, 32)
        phentsize, phnum, shentsize, shnum = struct.unpack_from(end + "HHHH", head, 54)
    else:
        phoff, shoff = struct.unpack_from(end + "II", head, 28)
        phentsize, phnum, shentsize, shnum = struct.unpack_from(end + "HHHH", head, 42)
    return phoff + phentsize * phnum <= size and shoff + shentsize * shnum <= size


def sound_bitcode(path: Path) -> bool:
    """True when a file is complete LLVM bitcode: its magic, then top-level blocks whose
    recorded lengths add up to the file's length (a truncated file fails this)."""
    try:
        data = path.read_bytes()
    except OSError:
        return False
    if data[:4] == b"\xde\xc0\x17\x0b":                      # bitcode wrapper header
        if len(data) < 20:
            return False
        offset, size = struct.unpack_from("<II", data, 8)
        if offset + size > len(data):
            return False
        data = data[offset:offset + size]
    if data[:4] != b"BC\xc0\xde":
        return False
    bits = int.from_bytes(data, "little")
    total, pos = 8 * len(data), 32

    def read(n):
        nonlocal pos
        if pos + n > total:
            raise EOFError
        v = (bits >> pos) & ((1 << n) - 1)
        pos += n
        return v

    def vbr(n):
        v, shift = 0, 0
        while True:
            chunk = read(n)
            v |= (chunk & ((1 << (n - 1)) - 1)) << shift
            shift += n - 1
            if not chunk >> (n - 1):
                return v
    blocks = 0
    try:
        while total - pos >= 32 and bits >> pos:               # zero words may pad the end
            if read(2) != 1:                                   # top level holds only blocks
                return False
            blocks += 1
            vbr(8)                                             # block id
            vbr(4)                                             # abbreviation width
            pos = -(-pos // 32) * 32
            words = read(32)                                   # block length in 32-bit words
            pos += 32 * words
        return blocks > 0 and pos <= total and not bits >> pos
    except EOFError:
        return False


def _sound(path: Path) -> bool:
    return sound_bitcode(path) if path.suffix == ".bc" else sound_elf(path)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


@contextmanager
def crash_guard(source: str, device, log=None):
    """Yields the cache-key attempt to build ``source`` with.  A marker file says this process is
    building and testing the program; a marker left by a process that died there (PoCL aborts
    the whole process on some broken cache entries, which no check in Python can catch) moves
    this program to the next cache key for good, so one crash does not break every later run."""
    key = _guard_key(source, device)
    d = cache_dir() / "building"
    salts = cache_dir() / "program-keys.json"
    try:
        d.mkdir(parents=True, exist_ok=True)
        attempt = int(read_json(salts).get(key, 0))
        dead = [m for m in d.glob(f"{key}.*") if m.suffix[1:].isdigit() and not _alive(int(m.suffix[1:]))]
        if dead:
            attempt += 1
            update_json(salts, key, attempt)
            for m in dead:
                m.unlink(missing_ok=True)
            if log:
                log(f"brdfcl: a run died building or testing this program on {device.name}; "
                    f"building it under a new PoCL cache key")
        marker = d / f"{key}.{os.getpid()}"
        marker.write_text("")
    except OSError:                     # no writable cache: build without the guard
        yield 0
        return
    try:
        yield attempt
    finally:
        marker.unlink(missing_ok=True)


def _guard_key(source: str, device) -> str:
    return hashlib.sha1(f"{device.name}\0{device.driver_version}\0{source}".encode()).hexdigest()[:20]


def keep_attempt(source: str, device, attempt: int) -> None:
    """A build under cache-key ``attempt`` worked where the one before failed: later runs start
    there (else each would meet the broken entry again, and the pip PoCL aborts at exit after a
    failed build)."""
    try:
        update_json(cache_dir() / "program-keys.json", _guard_key(source, device), attempt)
    except OSError:
        pass


def _dirs(path: str) -> list:
    try:
        with os.scandir(path) as it:
            return [e for e in it if e.is_dir(follow_symlinks=False)]
    except OSError:
        return []


def _cache_files(root: Path) -> list:
    """(file, its entry folder) as strings for the program bitcode (``*/*/*.bc``) and the kernel
    libraries (``*/*/*/*/*.so``, the entry three levels up) of a PoCL cache (a walk of plain
    strings: a cache of thousands of entries took pathlib's glob a second)."""
    out: list = []
    for a in _dirs(os.path.abspath(root)):
        for entry in _dirs(a.path):
            try:
                with os.scandir(entry.path) as it:
                    items = list(it)
            except OSError:
                continue
            for c in items:
                if c.name.endswith(".bc") and c.is_file(follow_symlinks=False):
                    out.append((c.path, entry.path))
                elif c.is_dir(follow_symlinks=False):
                    for d in _dirs(c.path):
                        try:
                            with os.scandir(d.path) as it:
                                out += [(f.path, entry.path) for f in it if f.name.endswith(".so")]
                        except OSError:
                            continue
    return out


def _fingerprints_file() -> Path:
    return cache_dir() / "pocl-fingerprints.json"


def _digest(path: str) -> str:
    return hashlib.sha1(Path(path).read_bytes()).hexdigest()


def _stat_print(st: os.stat_result, digest: str | None) -> list:
    """A file's print: size, modification and change times (ctime cannot be set back by a
    restore or ``touch``), and its SHA-1 where it passed a self-test (None: only found sound)."""
    return [st.st_size, st.st_mtime_ns, digest, st.st_ctime_ns]


def _digest_of(print_) -> str | None:
    """The digest of a print, None for a stat-only print or a malformed one."""
    return print_[2] if isinstance(print_, list) and len(print_) >= 3 and isinstance(print_[2], str) else None


def _matches(path: str, print_) -> bool:
    """True when a file is the one printed: same size and times, or else (a self-tested file
    only) the same content."""
    try:
        st = os.stat(path)
        size, mtime = print_[0], print_[1]
        ctime = print_[3] if len(print_) > 3 else None
        if st.st_size == size and st.st_mtime_ns == mtime and st.st_ctime_ns == ctime:
            return True
        digest = _digest_of(print_)
        return st.st_size == size and digest is not None and _digest(path) == digest
    except (OSError, ValueError, TypeError, IndexError, KeyError):
        return False


def _merge_prints(new: dict) -> None:
    """Add prints to the file, read again just before writing (another process may have written
    since): a self-test's print (with a digest) is never replaced by a stat-only one; prints of
    files gone are dropped."""
    prints = read_json(_fingerprints_file())
    for k, v in new.items():
        if _digest_of(v) is None and _digest_of(prints.get(k)) is not None and _matches(k, prints[k]):
            continue
        prints[k] = v
    write_json(_fingerprints_file(), {k: v for k, v in prints.items() if os.path.exists(k)})


def remember_pocl_cache(platform, since_ns: int) -> None:
    """Fingerprint the cache files PoCL wrote since ``since_ns`` (call it once their program has
    passed its self-test): a later run removes an entry whose file no longer matches."""
    root = pocl_cache_dir(platform)
    if root is None or not root.is_dir():
        return
    new = {}
    for path, _ in _cache_files(root):
        try:
            st = os.stat(path)
            if st.st_mtime_ns >= since_ns:
                new[path] = _stat_print(st, _digest(path))
        except OSError:
            continue
    if new:
        try:
            _merge_prints(new)
        except OSError:
            pass


def repair_pocl_cache(platform, log=None) -> list:
    """Remove cache entries with an incomplete file, or with a file that no longer matches its
    fingerprint (PoCL rebuilds them); once per process and cache.  A file found sound is
    remembered by its size and times, so a run reads only the files new or changed since the last
    (a cache of thousands of entries cost every start a second).  Returns the removed entry folders."""
    root = pocl_cache_dir(platform)
    if root is None or root in _REPAIRED or not root.is_dir():
        return []
    _REPAIRED.add(root)
    prints = read_json(_fingerprints_file())
    removed, checked = [], {}
    for path, entry in _cache_files(root):
        if entry in removed:
            continue
        known = prints.get(path)
        if known is not None and _matches(path, known):
            try:                # unchanged since it passed a self-test or this check: not read again
                fresh = _stat_print(os.stat(path), _digest_of(known))
                if fresh != known:          # same content, new times (or an older print): refresh
                    checked[path] = fresh
            except OSError:
                pass
            continue
        if _digest_of(known) is None and _sound(Path(path)):
            try:
                checked[path] = _stat_print(os.stat(path), None)
            except OSError:
                pass
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
    if checked or removed:      # remember what was checked, so that the next run reads only new files
        try:
            _merge_prints(checked)
        except OSError:
            pass
    if removed and log:
        log(f"brdfcl: removed a broken PoCL kernel-cache entr{'y' if len(removed) == 1 else f'ies ({len(removed)})'}"
            f" from {root}; PoCL compiles them again")
    return removed


KEEP_BINARIES = 32
"""Program binaries kept in brdfcl's cache (the newest; each some 0.2-1 MB)."""


def _options(attempt: int) -> list[str]:
    options = list(BUILD_OPTIONS)
    if attempt:
        # PoCL's cache key hashes the preprocessed source (comments are gone) and the build
        # options: a define in the options gives a fresh, separate entry.
        options.append(f"-DBRDFCL_CACHE_KEY={attempt}")
    return options


def binary_path(device, source: str, attempt: int = 0) -> Path:
    """Where brdfcl keeps the device binary of a program: keyed by the source, the build options
    and the device, its driver and its platform (a new runtime or driver builds afresh)."""
    p = device.platform
    ident = "\0".join((source, " ".join(_options(attempt)), device.name, device.version, device.driver_version,
                       p.name, p.version))
    return cache_dir() / "programs" / f"{hashlib.sha1(ident.encode()).hexdigest()[:32]}.bin"


def load_binary(ctx, device, source: str, attempt: int = 0):
    """(program, {name: kernel}) from the binary a successful build left (`keep_binary`), None when
    there is none or it does not load (then removed).  A cached build spares the runtime's own
    cache lookup, which preprocesses the whole source first (PoCL: 0.35-0.9 s a program)."""
    path = binary_path(device, source, attempt)
    try:
        binary = path.read_bytes()
    except OSError:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", cl.CompilerWarning)
            program = cl.Program(ctx, [device], [binary]).build(options=_options(attempt), devices=[device])
        return program, {k: cl.Kernel(program, k) for k in KERNELS}
    except (cl.Error, ValueError):
        forget_binary(device, source, attempt)
        return None


def keep_binary(program, device, source: str, attempt: int = 0) -> None:
    """Keep the device binary of a program that passed its self-test; the oldest beyond
    KEEP_BINARIES are removed.  An unwritable cache keeps nothing."""
    path = binary_path(device, source, attempt)
    try:
        binary = program.get_info(cl.program_info.BINARIES)[program.devices.index(device)]
        if not binary:
            return
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        tmp.write_bytes(binary)
        os.replace(tmp, path)
        kept = sorted(path.parent.glob("*.bin"), key=lambda f: f.stat().st_mtime, reverse=True)
        for old in kept[KEEP_BINARIES:]:
            old.unlink(missing_ok=True)
    except (OSError, cl.Error, ValueError):
        pass


def forget_binary(device, source: str, attempt: int = 0) -> None:
    """Remove a kept binary (it failed to load or its self-test)."""
    try:
        binary_path(device, source, attempt).unlink(missing_ok=True)
    except OSError:
        pass


def build(ctx, device, source: str, attempt: int = 0):
    """(program, {name: kernel}) for a source; ``attempt`` > 0 builds it under a new cache key."""
    options = _options(attempt)
    program = cl.Program(ctx, source)
    try:
        with warnings.catch_warnings():         # Intel's compiler always logs; failures are ours to tell
            warnings.simplefilter("ignore", cl.CompilerWarning)
            program.build(options=options, devices=[device])
        kernels = {k: cl.Kernel(program, k) for k in KERNELS}
    except cl.Error as e:
        f = buildlog.failure(e, f"build on {device.name}, options {' '.join(options)}")
        failed = ProgramError(buildlog.line(f"cannot build on {device.name}: ", f.cause, f.log), f.cause, f.log)
    else:
        return program, kernels
    del program
    gc.collect()                # release the failed program now: PoCL cannot tear down its IR later
    raise failed


def build_log(program, device) -> str:
    try:
        return program.get_build_info(device, cl.program_build_info.LOG) or ""
    except cl.Error:
        return ""
