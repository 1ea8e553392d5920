"""OpenCL platform and device choice.

Default: the first device with float64 that can build a program (brdfcl.device.buildcheck), in
this order: the PoCL platforms, newest first (Debian's 3.1 build before the pip wheel's 3.0),
then Intel's CPU runtime, then any other.  A platform that cannot build is left out, with one
line saying why in the run that first finds it out (`brdfcl info` always lists it).
``BRDFCL_DEVICE`` or ``--device`` pick another: an index ``P:D`` or ``D`` (into the flat list of
``brdfcl info``) or a substring of the platform's name or version (``intel``, ``pocl 3.0``), else
of the device's name or kind (``nvidia``, ``cpu``); of several, the first that builds.  The
runtimes pip installed are made loadable before the first listing (brdfcl.device.runtimes).
"""
from __future__ import annotations

import logging
import os
import re

from brdfcl.device import buildcheck, buildlog, runtimes
from brdfcl.device.errors import DeviceError

__all__ = ["DeviceError", "all_devices", "check", "describe", "has_fp64", "pick_device", "usable"]


def _cl():
    runtimes.prepare()
    try:
        import pyopencl as cl
    except ImportError as e:  # pragma: no cover
        raise DeviceError(f"pyopencl is not installed: {e}") from None
    return cl


def all_devices():
    """[(platform, device)] in platform order."""
    cl = _cl()
    try:
        plats = cl.get_platforms()
    except cl.Error as e:
        raise DeviceError(f"no OpenCL platform found ({e}); install pyopencl[pocl] or an ICD") from None
    return [(p, d) for p in plats for d in p.get_devices()]


def short_name(device) -> str:
    """A device's name for a one-line message: PoCL's CPU devices without their
    ``pthread-<LLVM CPU>-`` prefix (``pthread-skylake-avx512-Intel(R) Xeon(R) Processor`` is the
    Xeon), other names as the driver gives them."""
    return re.sub(r"^pthread-[a-z0-9_.-]*?(?=[A-Z])", "", device.name)


def has_fp64(device):
    return bool(device.double_fp_config) or "cl_khr_fp64" in device.extensions


def describe_device(i, p, d):
    """Two lines on one device for `brdfcl info`: what its driver reports about itself."""
    return [f"[{i}] {p.name} | {p.version}",
            f"     {d.name} ({_kind(d)}), {d.max_compute_units} compute units, "
            f"{d.global_mem_size / 2**30:.1f} GiB, float64: {'yes' if has_fp64(d) else 'no'}, "
            f"reported vector width float/double: {d.preferred_vector_width_float}/"
            f"{d.preferred_vector_width_double}"]


def describe(chosen=None):
    """Lines on every device, as `brdfcl info` prints them: what it reports and whether it builds
    (``chosen``: the (platform, device) to mark as chosen)."""
    devs = all_devices()
    return [line for i, (p, d) in enumerate(devs)
            for line in describe_device(i, p, d) + [f"     {status(i, devs, chosen)}"]]


def pocl_version(platform) -> tuple:
    """(major, minor, is_release) of a PoCL platform, for ordering; (0, 0, 0) if unknown."""
    m = re.search(r"PoCL (\d+)\.(\d+)(\S*)", platform.version)
    return (int(m.group(1)), int(m.group(2)), "rc" not in m.group(3)) if m else (0, 0, 0)


def _kind(d):
    cl = _cl()
    t = d.type
    return "GPU" if t & cl.device_type.GPU else "CPU" if t & cl.device_type.CPU else "accelerator"


def selector_of(platform, device) -> str:
    """``P:D``, the platform and device indices that name this device in another process."""
    for pi, p in enumerate(_cl().get_platforms()):
        if p.int_ptr == platform.int_ptr:
            for di, d in enumerate(p.get_devices()):
                if d.int_ptr == device.int_ptr:
                    return f"{pi}:{di}"
    raise DeviceError(f"device {device.name} not found among the OpenCL platforms")


def check(index: int, devs=None) -> buildcheck.Check:
    """Whether the ``index``-th device of ``all_devices()`` can build a program (cached)."""
    devs = devs if devs is not None else all_devices()
    p, d = devs[index]
    return buildcheck.check(p, d, selector_of(p, d))


def is_pocl(platform) -> bool:
    return "portable computing" in platform.name.lower()


def is_cpu(device) -> bool:
    return _kind(device) == "CPU"


def usable(keep=None) -> list:
    """[(flat index, platform, device, Check)] of every device (those ``keep(p, d)`` accepts), with
    whether it builds: for `brdfcl info`, tests and benchmarks that run on each runtime."""
    devs = all_devices()
    return [(i, p, d, check(i, devs)) for i, (p, d) in enumerate(devs) if keep is None or keep(p, d)]


def preference(devs) -> list:
    """Indices of ``devs`` in the order of the default choice (see the module docstring)."""
    def rank(i):
        p, d = devs[i]
        intel_cpu = "intel" in p.name.lower() and is_cpu(d)
        major, minor, release = pocl_version(p)
        return (not has_fp64(d), 0 if is_pocl(p) else 1 if intel_cpu else 2, -major, -minor, not release, i)
    return sorted(range(len(devs)), key=rank)


def status(index: int, devs, chosen=None) -> str:
    """One line on whether a device builds programs (and is the one chosen), for `brdfcl info`."""
    c = check(index, devs)
    p, d = devs[index]
    mark = "; chosen" if chosen is not None and (p.int_ptr, d.int_ptr) == (chosen[0].int_ptr, chosen[1].int_ptr) else ""
    if c.ok:
        return f"status: builds programs{mark}"
    return buildlog.line("status: cannot build a program: ", c.reason, c.log, mark)


_NOTED: set = set()


def _note(message: str) -> None:
    """A line for the user, once per process (the default choice is made by every engine)."""
    if message not in _NOTED:
        _NOTED.add(message)
        logging.getLogger("brdfcl").warning(message)


def pick_device(selector: str | None = None):
    """(platform, device) for a selector; see the module docstring."""
    selector = selector if selector is not None else os.environ.get("BRDFCL_DEVICE")
    devs = all_devices()
    if not devs:
        raise DeviceError(f"no OpenCL device found; to get one: {runtimes.install_hint()}")
    if selector in (None, "", "default"):
        left_out: list[str] = []
        told = False                    # said once per machine: when the check is made
        for i in preference(devs):
            c = check(i, devs)
            if c.ok:
                p, d = devs[i]
                if left_out and told:
                    _note(buildlog.line("brdfcl: ", "; ".join(left_out), None,
                                        f"; using {buildcheck.label(p)} ({d.name})"))
                return p, d
            left_out.append(f"{buildcheck.label(devs[i][0])}: {c.reason}")
            told |= c.fresh
        more = f"; +{len(left_out) - 1} in brdfcl info" if len(left_out) > 1 else ""
        raise DeviceError(buildlog.line("no OpenCL device builds here (", left_out[0],
                                        None, f"{more}); to get one: {runtimes.install_hint()}"))
    i = _select(selector, devs)
    c = check(i, devs)
    if not c.ok:
        raise DeviceError(buildlog.line(f"device '{selector}' ({buildcheck.label(devs[i][0])}) cannot build a "
                                        "program: ", c.reason, c.log))
    return devs[i]


def _select(selector: str, devs) -> int:
    """The index into ``devs`` that a selector names: an index, else the devices whose platform's
    name or version holds it (``intel`` is Intel's runtime, not PoCL on an Intel CPU), else those
    whose device name or kind does; of several, the first that builds."""
    if selector.replace(":", "").isdigit():
        if ":" in selector:
            pi, di = (int(s) for s in selector.split(":"))
            for i, (p, d) in enumerate(devs):
                if selector_of(p, d) == f"{pi}:{di}":
                    return i
        elif int(selector) < len(devs):
            return int(selector)
        raise DeviceError(f"no OpenCL device '{selector}'; {_choices(devs)}")
    s = selector.lower()
    hits = ([i for i, (p, d) in enumerate(devs) if s in p.name.lower() or s in p.version.lower()]
            or [i for i, (p, d) in enumerate(devs) if s in d.name.lower() or s == _kind(d).lower()])
    if not hits:
        raise DeviceError(f"no OpenCL device matches '{selector}'; {_choices(devs)}")
    order = preference(devs)
    hits.sort(key=order.index)
    return next((i for i in hits if check(i, devs).ok), hits[0])


def _choices(devs):
    """The devices as one short line, for errors (``brdfcl info`` lists them in full)."""
    return "devices: " + "; ".join(f"[{i}] {buildcheck.label(p)} {_kind(d)}" for i, (p, d) in enumerate(devs))
