"""The OpenCL devices of this machine as test parameters: each device that can build a program
is a case; each that cannot is a skipped case whose reason names the runtime and the cause
(the pip wheel's PoCL on a CPU newer than its LLVM), so a run says what it did not cover."""
import pytest


def device_params(keep=None):
    """pytest params (flat device index as a string) of the devices ``keep(p, d)`` accepts."""
    try:
        from brdfcl.device.buildcheck import label
        from brdfcl.device.platforms import usable
        found = usable(keep)
    except Exception as e:              # no pyopencl or no platform
        return [pytest.param(None, marks=pytest.mark.skip(reason=f"no OpenCL device: {e}"))]
    return [pytest.param(str(i), marks=() if c.ok else pytest.mark.skip(reason=f"{label(p)} on this CPU: {c.reason}"),
                         id=f"{label(p)}-{d.name[:24]}".replace(" ", "_")) for i, p, d, c in found]


def is_pocl(p, d):
    from brdfcl.device.platforms import is_pocl
    return is_pocl(p)


def is_cpu(p, d):
    from brdfcl.device.platforms import is_cpu
    return is_cpu(d)


def building(keep=None):
    """Flat indices (strings) of the devices ``keep(p, d)`` accepts that can build a program."""
    try:
        from brdfcl.device.platforms import usable
        return [str(i) for i, p, d, c in usable(keep) if c.ok]
    except Exception:                   # no pyopencl or no platform
        return []
