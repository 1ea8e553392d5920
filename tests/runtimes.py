"""The OpenCL devices of this machine as test parameters: each device that can build a program
is a case; each that cannot is a skipped case whose reason names the runtime and the cause
(the pip wheel's PoCL on a CPU newer than its LLVM), so a run says what it did not cover."""
import pytest


def device_params(keep=lambda p, d: True):
    """pytest params (flat device index as a string) of the devices ``keep`` accepts."""
    try:
        from brdfcl.device.buildcheck import label
        from brdfcl.device.platforms import all_devices, check
        devs = all_devices()
    except Exception as e:              # no pyopencl or no platform
        return [pytest.param(None, marks=pytest.mark.skip(reason=f"no OpenCL device: {e}"))]
    out = []
    for i, (p, d) in enumerate(devs):
        if not keep(p, d):
            continue
        c = check(i, devs)
        marks = () if c.ok else pytest.mark.skip(reason=f"{label(p)} on this CPU: {c.reason}")
        out.append(pytest.param(str(i), marks=marks, id=f"{label(p)}-{d.name[:24]}".replace(" ", "_")))
    return out


def is_pocl(p, d):
    return "portable computing" in p.name.lower()


def is_cpu(p, d):
    import pyopencl as cl
    return bool(d.type & cl.device_type.CPU)


def building(keep=lambda p, d: True):
    """Flat indices (strings) of the devices ``keep`` accepts that can build a program."""
    return [prm.values[0] for prm in device_params(keep) if not prm.marks and prm.values[0] is not None]
