"""The vector width of a CPU device's programs, decided by building and testing, not by asking.

A device's preferred vector width is what its driver believes, not what its
compiler targets: PoCL 3.0's pip build on an AMD Zen 4 reports 16 floats (the CPU
has AVX-512) but compiles for ``znver3`` (no AVX-512), and width-16 programs then
crash or compute garbage.  So the width is chosen by trial, widest first: a child
process (`brdfcl.device.probe`, so that a crash cannot take the caller down) builds the
default model at that width, reads the build log for ABI warnings and runs the
known-answer self-test (`brdfcl.device.selftest`) on its kernels; the first width that
passes is used.  The decision is cached per device, driver, CPU and kernel
sources (``~/.cache/brdfcl/vector-widths.json``, or ``BRDFCL_CACHE_DIR``), so only
the first process on a machine pays for it.  ``BRDFCL_VECTOR_WIDTH`` (or
``--vector-width`` / ``FitOptions.vector_width``) overrides the choice.  GPUs run
one cell per work-item (width 1); every program is self-tested in-process anyway.
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pyopencl as cl

from brdfcl._cache import cache_dir, locked, read_json, update_json
from brdfcl._version import __version__
from brdfcl.device import buildlog, cpu
from brdfcl.device.build import ABI_WARNING
from brdfcl.device.errors import ProgramError
from brdfcl.device.platforms import is_cpu, selector_of
from brdfcl.kernels.codegen import kernel_sources_hash

ENV = "BRDFCL_VECTOR_WIDTH"
WIDTHS = (1, 2, 4, 8, 16)
PROBE_TIMEOUT_S = 600


@dataclass(frozen=True)
class WidthChoice:
    width: int
    reason: str                  # why this width: forced, device kind, or the probes' outcomes
    selftest: str                # the self-test result of the chosen width ("" if not run yet)

    def __str__(self):
        return f"{self.width} ({self.reason}; self-test {self.selftest or 'when built'})"


def check_width(value, source=ENV) -> int:
    try:
        w = int(value)
    except (TypeError, ValueError):
        w = -1
    if w not in WIDTHS:
        raise ValueError(f"{source}={value!r}: vector width must be one of {', '.join(map(str, WIDTHS))}")
    return w


def forced_width(explicit=None) -> WidthChoice | None:
    """An explicit width (argument, then the environment), or None to choose by probing."""
    if explicit is not None:
        return WidthChoice(check_width(explicit, "vector_width"), "forced by --vector-width", "")
    env = os.environ.get(ENV)
    if env:
        return WidthChoice(check_width(env), f"forced by {ENV}", "")
    return None


def preferred(device, real) -> int:
    raw = device.preferred_vector_width_float if real == "float" else device.preferred_vector_width_double
    return max(w for w in WIDTHS if w <= min(16, raw or 1))


def candidates(device, real) -> list:
    """Widths to try on a device, widest first: on a CPU from the wider of what the device
    reports and what the CPU's own registers hold (Intel's runtime reports one float on an
    AVX-512 CPU, where 16 run fastest), down to one."""
    if not is_cpu(device):
        return [1]
    top = max(preferred(device, real), min(16, cpu.native_width(real)))
    return [w for w in reversed(WIDTHS) if w <= top]


def device_key(platform, device, real) -> str:
    """What the decision depends on: driver, device, the CPU's instruction sets, our kernels."""
    parts = [platform.name, platform.version, device.name, device.vendor, device.driver_version,
             cpu.flags() if is_cpu(device) else "", cl.VERSION_TEXT, __version__, kernel_sources_hash(), real]
    return hashlib.sha1("\n".join(parts).encode()).hexdigest()[:20]


def probe(selector: str, real: str, width: int) -> dict:
    """Build and self-test the default model at ``width`` in a child process: {ok, detail, ...}."""
    return run_probe([sys.executable, "-m", "brdfcl.device.probe", "--device", selector, "--real", real,
                      "--width", str(width)], width)


def run_probe(cmd, width=None) -> dict:
    """Run a probe command; a crash, a non-zero exit or ABI warnings are failures."""
    env = {k: v for k, v in os.environ.items() if k != ENV}
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=PROBE_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return {"ok": False, "detail": f"no answer in {PROBE_TIMEOUT_S} s"}
    if r.returncode < 0:
        return {"ok": False, "detail": f"crashed (signal {-r.returncode})"}
    try:
        res = json.loads(r.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        return {"ok": False, "detail": f"exit status {r.returncode}: {tail[:200]}"}
    n_abi = (r.stdout + r.stderr).count(ABI_WARNING) + res.pop("abi_warnings", 0)
    if res.get("ok") and n_abi:
        res.update(ok=False, detail=f"{n_abi} compiler warnings that width {width} changes the ABI "
                                    f"(the compiler targets narrower vectors than the device reports)")
    return res


def choose(platform, device, real, explicit=None, log=None, probe_fn=None) -> WidthChoice:
    """The vector width for programs of precision ``real`` on a device (see the module docstring)."""
    forced = forced_width(explicit)
    if forced is not None:
        return forced
    widths = candidates(device, real)
    if len(widths) == 1:
        return WidthChoice(widths[0], "not a CPU: one cell per work-item", "")
    path = cache_dir() / "vector-widths.json"
    key = device_key(platform, device, real)
    hit = _entry(read_json(path), key)
    if hit is None:
        with locked(path):
            hit = _entry(read_json(path), key)        # another process may have probed meanwhile
            if hit is None:
                hit = _probe_all(platform, device, real, widths, log, probe_fn or probe)
                try:
                    update_json(path, key, hit)
                except OSError as e:
                    if log:
                        log(f"could not cache the vector width in {path}: {e}")
    return WidthChoice(hit["width"], hit["reason"], hit["selftest"])


def _entry(table: dict, key: str) -> dict | None:
    """A cached decision, or None when it is missing or not one this module wrote (probe again)."""
    e = table.get(key)
    ok = (isinstance(e, dict) and e.get("width") in WIDTHS and isinstance(e.get("reason"), str)
          and isinstance(e.get("selftest"), str))
    return e if ok else None


def _probe_all(platform, device, real, widths, log, probe_fn) -> dict:
    selector = selector_of(platform, device)
    tried: dict[str, list[int]] = {}            # each outcome with the widths that had it
    logs = []
    for w in widths:
        if log:
            log(f"checking vector width {w} ({real}) on {device.name}: build and self-test")
        res = probe_fn(selector, real, w)
        if res.get("ok"):
            why = (f"device reports {preferred(device, real)}, the CPU holds {cpu.native_width(real)}"
                   + (f"; {_outcomes(tried)}" if tried else "") + f"; {w} passed")
            return {"width": w, "reason": why, "selftest": res.get("detail", "passed"),
                    "device": device.name, "platform": platform.version, "real": real}
        tried.setdefault(str(res.get("detail", "?")), []).append(w)
        logs += [res["log"]] if res.get("log") else []
    log_path = Path(logs[0]) if logs else None
    raise ProgramError(buildlog.line(f"no vector width works on {device.name} ({real}): ", _outcomes(tried),
                                     log_path), _outcomes(tried), log_path)


def _outcomes(tried: dict) -> str:
    """``16, 8 failed: crashed (signal 11); 4 failed: ...``, each outcome cut to one short clause."""
    def short(detail):
        return detail if len(detail) <= 60 else detail[:57] + "..."
    return "; ".join(f"{', '.join(map(str, ws))} failed: {short(d)}" for d, ws in tried.items())


def describe(platform, device, real, log=None) -> str:
    try:
        return str(choose(platform, device, real, log=log))
    except (ProgramError, ValueError) as e:
        return f"none: {e}"
