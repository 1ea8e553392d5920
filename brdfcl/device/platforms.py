"""OpenCL platform and device choice.

Default: the first CPU device of the newest PoCL platform (Debian's 3.1 build is
preferred to the pip wheel's 3.0 when both are present), else the
first device with float64.  ``BRDFCL_DEVICE`` or ``--device`` pick another:
an index ``P:D`` or ``D`` (into the flat list of ``brdfcl info``) or a
substring of the platform's name or version or of the device's name (``nvidia``,
``pocl 3.0``, ``cpu``).
"""
from __future__ import annotations

import os
import re


class DeviceError(RuntimeError):
    pass


def _cl():
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


def has_fp64(device):
    return bool(device.double_fp_config) or "cl_khr_fp64" in device.extensions


def describe_device(i, p, d):
    """Two lines on one device for `brdfcl info`: what its driver reports about itself."""
    return [f"[{i}] {p.name} | {p.version}",
            f"     {d.name} ({_kind(d)}), {d.max_compute_units} compute units, "
            f"{d.global_mem_size / 2**30:.1f} GiB, float64: {'yes' if has_fp64(d) else 'no'}, "
            f"reported vector width float/double: {d.preferred_vector_width_float}/"
            f"{d.preferred_vector_width_double}"]


def describe():
    """Lines for `brdfcl info`."""
    return [line for i, (p, d) in enumerate(all_devices()) for line in describe_device(i, p, d)]


def pocl_version(platform) -> tuple:
    """(major, minor, is_release) of a PoCL platform, for ordering; (0, 0, 0) if unknown."""
    m = re.search(r"PoCL (\d+)\.(\d+)(\S*)", platform.version)
    return (int(m.group(1)), int(m.group(2)), "rc" not in m.group(3)) if m else (0, 0, 0)


def _kind(d):
    cl = _cl()
    t = d.type
    return "GPU" if t & cl.device_type.GPU else "CPU" if t & cl.device_type.CPU else "accelerator"


def pick_device(selector: str | None = None):
    """(platform, device) for a selector; see the module docstring."""
    selector = selector if selector is not None else os.environ.get("BRDFCL_DEVICE")
    devs = all_devices()
    if not devs:
        raise DeviceError("no OpenCL device found; install pyopencl[pocl] for the CPU device")
    if selector in (None, "", "default"):
        pocl = [pd for pd in devs if "portable computing" in pd[0].name.lower()]
        # The newest PoCL first: Debian's pocl-opencl-icd (3.1) before the pip wheel's (3.0-rc2).
        pocl.sort(key=lambda pd: pocl_version(pd[0]), reverse=True)
        for p, d in pocl + devs:
            if has_fp64(d):
                return p, d
        return devs[0]
    if selector.replace(":", "").isdigit():
        if ":" in selector:
            pi, di = (int(s) for s in selector.split(":"))
            plats = _cl().get_platforms()
            try:
                return plats[pi], plats[pi].get_devices()[di]
            except IndexError:
                pass
        elif int(selector) < len(devs):
            return devs[int(selector)]
        raise DeviceError(f"no OpenCL device '{selector}'; {_choices(devs)}")
    s = selector.lower()
    for p, d in devs:
        if s in p.name.lower() or s in p.version.lower() or s in d.name.lower() or s == _kind(d).lower():
            return p, d
    raise DeviceError(f"no OpenCL device matches '{selector}'; {_choices(devs)}")


def _choices(devs):
    """The devices as one line, for errors (``brdfcl info`` lists them in full)."""
    return "devices: " + "; ".join(f"[{i}] {d.name} on {p.version.split('  ')[0]}" for i, (p, d) in enumerate(devs))
