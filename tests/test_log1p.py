"""The kernels' inline log1p (brdfcl/kernels/log1p.py) against float64: its numpy twin and the
compiled function on every OpenCL device present, at vector widths 1 and 16."""
import numpy as np
import pytest

from brdfcl.kernels import log1p

pytest.importorskip("pyopencl")
import pyopencl as cl  # noqa: E402

from brdfcl.device.platforms import all_devices  # noqa: E402

MAX_ULP = 1.5


def _inputs():
    rng = np.random.default_rng(3)
    xs = [np.geomspace(1e-30, 3e38, 400_001), np.linspace(0, 4, 200_001),
          np.linspace(-0.999, 0, 20_001), rng.uniform(0, 100, 100_000),
          # around the range reduction's boundaries (u = sqrt(2) 2^k)
          np.concatenate([np.sqrt(2) * 2.0**k * (1 + np.linspace(-1e-6, 1e-6, 201)) - 1 for k in range(-1, 30)])]
    return np.concatenate(xs).astype(np.float32)


def _ulps(got, x):
    truth = np.log1p(x.astype(np.float64))
    return np.abs(got.astype(np.float64) - truth) / np.spacing(np.abs(truth).astype(np.float32)).astype(np.float64)


def test_fit_reproduces_the_committed_coefficients():
    assert np.allclose(log1p.fit(), log1p.COEFFS, rtol=1e-5, atol=1e-7)


def test_numpy_twin_within_1_5_ulp():
    x = _inputs()
    assert _ulps(log1p.log1p_f32(x), x).max() <= MAX_ULP
    special = log1p.log1p_f32(np.array([0, np.inf, np.nan, -0.5, 3.4e38], np.float32))
    assert special[0] == 0 and special[1] == np.inf and np.isnan(special[2])
    assert special[3] == np.float32(np.log1p(-0.5)) or abs(special[3] - np.log1p(-0.5)) < 1e-7
    assert abs(special[4] - np.log1p(3.4e38)) < 1e-5


def _devices():
    return [pytest.param(d, id=f"{p.version.split()[2]}-{d.name[:24]}") for p, d in all_devices()]


@pytest.mark.parametrize("device", _devices())
@pytest.mark.parametrize("vw", [1, 16])
def test_device_function_within_1_5_ulp(device, vw):
    real, cond = ("float", "int") if vw == 1 else (f"float{vw}", f"int{vw}")
    src = log1p.c_source(real, cond) + f"""
__kernel void run(__global const float *x, __global float *y)
{{
    const int i = get_global_id(0);
    {"y[i] = brdfcl_log1p(x[i]);" if vw == 1 else
     f"*(__global {real} *)(y + {vw} * i) = brdfcl_log1p(*(__global const {real} *)(x + {vw} * i));"}
}}
"""
    ctx = cl.Context([device])
    queue = cl.CommandQueue(ctx)
    prg = cl.Program(ctx, src).build()
    x = np.concatenate([_inputs(), np.array([0, np.inf, np.nan, 3.4e38], np.float32)])
    x = np.concatenate([x, np.zeros(-len(x) % 16, np.float32)])
    y = np.empty_like(x)
    mf = cl.mem_flags
    xb = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x)
    yb = cl.Buffer(ctx, mf.WRITE_ONLY, y.nbytes)
    prg.run(queue, (len(x) // vw,), None, xb, yb)
    cl.enqueue_copy(queue, y, yb)
    finite = np.isfinite(x)
    assert _ulps(y[finite], x[finite]).max() <= MAX_ULP
    assert np.isinf(y[np.isinf(x)]).all() and np.isnan(y[np.isnan(x)]).all()
    # the same arithmetic as the numpy twin: at most one rounding apart (FMA contraction may differ)
    twin = log1p.log1p_f32(x[finite])
    assert (np.abs(y[finite] - twin) <= np.spacing(np.abs(twin))).all()
