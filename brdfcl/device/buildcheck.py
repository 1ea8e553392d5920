"""Whether an OpenCL device can build a program at all, decided once per machine.

The pip wheel's PoCL (LLVM 14) builds nothing on a CPU newer than its LLVM: it names the CPU
``generic`` and then rejects that name ("unknown target CPU 'generic'").  Such a device is no
candidate for the default choice and no device to probe vector widths on: brdfcl.device.platforms
leaves it out with the one line `Check.reason` gives.  The check builds a one-line kernel in a child
process (the pip PoCL can abort at exit after a failed build, and a crash must not take the
caller down); its answer is cached per platform, device, driver and CPU (``platform-checks.json``
in brdfcl's cache), so a machine pays for it once.

Run as ``python -m brdfcl.device.buildcheck --device P:D``: prints one JSON line.  Tests make a
platform's check fail for real by naming part of its name or version in ``BRDFCL_BREAK_PLATFORM``
(its one-line kernel then carries an ``#error``), as a CPU its compiler does not know would.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
import warnings
from dataclasses import dataclass, field

from brdfcl._cache import cache_dir, locked, read_json, update_json
from brdfcl.device import cpu, runtimes

KERNEL = "__kernel void brdfcl_check(__global float *x) { x[get_global_id(0)] *= 2.0f; }\n"
BREAK_ENV = "BRDFCL_BREAK_PLATFORM"
TIMEOUT_S = 300
_VERSION = 1                     # of this check: a change of it checks every device again
_CHECKED: dict = {}


@dataclass(frozen=True)
class Check:
    ok: bool
    reason: str = ""             # why not, one short line ("" when it builds)
    log: str | None = None       # the file with the whole build log
    fresh: bool = field(default=False, compare=False)     # decided in this process, not read back

    def __str__(self):
        return "builds" if self.ok else f"cannot build: {self.reason}"


def label(platform) -> str:
    """A platform's short name for messages: ``PoCL 3.0-rc2``, ``Intel(R) OpenCL``."""
    m = re.search(r"PoCL (\S+)", platform.version)
    return f"PoCL {m.group(1)}" if m else platform.name.strip()


def explain(platform, cause: str) -> str:
    """A build failure's cause in a user's words where it is a known one."""
    m = re.search(r"unknown target CPU '([^']*)'", cause)
    if m:
        llvm = re.search(r"LLVM (\d+)", platform.version)
        return f"its LLVM {llvm.group(1) if llvm else ''} does not know this CPU ({m.group(1)})".replace("  ", " ")
    return cause


def _broken(platform) -> bool:
    want = os.environ.get(BREAK_ENV, "").strip().lower()
    return bool(want) and (want in platform.name.lower() or want in platform.version.lower())


def key(platform, device) -> str:
    """What the check's answer depends on: platform, device, driver, CPU, PoCL's settings."""
    import pyopencl as cl
    pocl = [f"{k}={v}" for k, v in sorted(os.environ.items()) if k.startswith("POCL_") and k != "POCL_CACHE_DIR"]
    parts = [str(_VERSION), platform.name, platform.version, device.name, device.driver_version,
             cpu.flags(), cl.VERSION_TEXT, os.environ.get(BREAK_ENV, ""), *pocl]
    return hashlib.sha1("\n".join(parts).encode()).hexdigest()[:20]


def check(platform, device, selector: str, run=None) -> Check:
    """Whether ``device`` builds a one-line kernel; ``selector`` (``P:D``) names it in a child
    process.  Cached in this process and, where the compiler itself answered, on disk (a crash
    or a timeout is checked again by the next process); ``run`` replaces the child (tests)."""
    k = key(platform, device)
    if k in _CHECKED:
        return _CHECKED[k]
    path = cache_dir() / "platform-checks.json"
    hit = read_json(path).get(k)
    if isinstance(hit, dict) and isinstance(hit.get("ok"), bool) and isinstance(hit.get("reason"), str):
        res = Check(hit["ok"], hit["reason"], hit.get("log"))
    else:
        got, final = (run or _run_child)(selector, k)
        res = Check(got.ok, explain(platform, got.reason) if not got.ok else "", got.log, fresh=True)
        if final:
            try:
                with locked(path):
                    update_json(path, k, {"ok": res.ok, "reason": res.reason, "log": res.log,
                                          "device": device.name, "platform": platform.version})
            except OSError:
                pass
    _CHECKED[k] = res
    return res


def _run_child(selector: str, expect: str) -> tuple[Check, bool]:
    """(the child's answer, whether it is the compiler's own and may be cached)."""
    cmd = [sys.executable, "-m", "brdfcl.device.buildcheck", "--device", selector, "--key", expect]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return Check(False, f"no answer in {TIMEOUT_S} s to building a one-line kernel"), False
    for line in reversed(r.stdout.strip().splitlines()):
        try:
            got = json.loads(line)
        except ValueError:
            continue
        if isinstance(got, dict) and "ok" in got:
            return Check(bool(got["ok"]), str(got.get("reason", "")), got.get("log")), bool(got.get("final"))
    if r.returncode < 0:
        return Check(False, f"crashed building a one-line kernel (signal {-r.returncode})"), False
    tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
    return Check(False, f"exit status {r.returncode} building a one-line kernel: {tail[:80]}"), False


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m brdfcl.device.buildcheck")
    ap.add_argument("--device", required=True, help="P:D, the platform and device indices")
    ap.add_argument("--key", default="", help="the device's key in the caller (refuse another device)")
    a = ap.parse_args(argv)
    runtimes.prepare()
    import pyopencl as cl

    from brdfcl.device import buildlog
    from brdfcl.device.poclcache import repair_pocl_cache
    pi, di = (int(s) for s in a.device.split(":"))
    platform = cl.get_platforms()[pi]
    device = platform.get_devices()[di]
    if a.key and key(platform, device) != a.key:
        out: dict = {"ok": False, "reason": f"device {a.device} is another device in a new process", "final": False}
        print(json.dumps(out), flush=True)
        return 0
    repair_pocl_cache(platform)
    source = ("#error injected build failure\n" if _broken(platform) else "") + KERNEL
    try:
        ctx = cl.Context([device])
        program = cl.Program(ctx, source)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", cl.CompilerWarning)
            program.build(devices=[device])
        out = {"ok": True, "final": True}
    except cl.Error as e:
        f = buildlog.failure(e, f"one-line kernel on {device.name} ({platform.version})")
        # a build that failed is the compiler's answer; a context that could not be made may not be
        final = "BUILD_PROGRAM_FAILURE" in buildlog.error_text(e)
        out = {"ok": False, "reason": f.cause, "log": str(f.log) if f.log else None, "final": final}
    print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
