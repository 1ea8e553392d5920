"""The kernels' inline log1p, log, exp and erfc (brdfcl/kernels/inline_math.py) against float64:
their numpy twins and the compiled functions on every OpenCL device present, at vector widths 1
and 16."""
import math

import numpy as np
import pytest

from brdfcl.kernels import inline_math as im

MAX_ULP = {"log1p": 1.5, "log": 1.5, "exp": 1.3, "erfc": 8.0}
TWIN_ULP = {"erfc": 4.0}       # its division may round otherwise on a device, and t enters the exponent
TRUTH = {"log1p": np.log1p, "log": np.log, "exp": np.exp, "erfc": np.frompyfunc(math.erfc, 1, 1)}
SPECIAL = np.array([0, np.inf, -np.inf, np.nan, 3.4e38, -0.5, -2.0, 88.7, 89.0, -104.5], np.float32)


def _inputs(name):
    rng = np.random.default_rng(3)
    if name == "erfc":            # where erfc is a normal float, and around the split of z's bits
        xs = [np.linspace(-9.1, 9.1, 400_001), np.geomspace(1e-30, 9.1, 200_001), rng.normal(0, 3, 100_000),
              np.concatenate([2.0**k * (1 + np.linspace(-1e-6, 1e-6, 201)) for k in range(-3, 4)])]
        return np.concatenate(xs).astype(np.float32)
    if name == "exp":
        xs = [np.linspace(-87.3, 88.72, 400_001), np.linspace(-1, 1, 200_001), rng.normal(0, 10, 100_000)]
    else:
        lo = 0.0 if name == "log1p" else 1.2e-38
        xs = [np.geomspace(max(lo, 1e-30), 3e38, 400_001), np.linspace(lo, 4, 200_001), rng.uniform(lo, 100, 100_000),
              # around the range reduction's boundaries (sqrt(2) 2^k)
              np.concatenate([np.sqrt(2) * 2.0**k * (1 + np.linspace(-1e-6, 1e-6, 201)) for k in range(-1, 30)])]
        if name == "log1p":
            xs.append(np.linspace(-0.999, 0, 20_001))
    return np.concatenate(xs).astype(np.float32)


def _ulps(got, x, name):
    truth = TRUTH[name](x.astype(np.float64)).astype(np.float64)
    return np.abs(got.astype(np.float64) - truth) / np.spacing(np.abs(truth).astype(np.float32)).astype(np.float64)


def _special_ok(got, name):
    with np.errstate(all="ignore"):
        want = TRUTH[name](SPECIAL.astype(np.float64)).astype(np.float64).astype(np.float32)
    if name == "log1p":
        want[SPECIAL < -1] = got[SPECIAL < -1]                # outside its domain: not specified
    if name == "exp":
        want[SPECIAL == -104.5] = 0                           # below EXP_LO: 0
    with np.errstate(invalid="ignore"):
        same = (got == want) | (np.isnan(got) & np.isnan(want)) | (np.abs(got - want) <= 2e-7 * np.abs(want))
    return same.all(), dict(zip(SPECIAL.tolist(), got.tolist()))


def test_fits_reproduce_the_committed_coefficients():
    assert np.allclose(im.fit_log(), im.LOG_COEFFS, rtol=1e-5, atol=1e-7)
    assert np.allclose(im.fit_exp(), im.EXP_COEFFS, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("name", im.NAMES)
def test_numpy_twin_against_float64(name):
    x = _inputs(name)
    assert _ulps(im.TWINS[name](x), x, name).max() <= MAX_ULP[name]
    ok, got = _special_ok(im.TWINS[name](SPECIAL), name)
    assert ok, got


def _devices():
    """Every device of this machine (a flat index), skipped with the reason where it cannot build."""
    from tests.runtimes import device_params
    return device_params()


def test_float32_kernels_take_them_and_float64_kernels_the_builtins():
    from brdfcl.kernels.codegen import KernelOptions, render
    from brdfcl.model.compose import Model
    model = Model("diffuse+diffraction+gtr:smith:dielectric")     # log1p (metric), log and exp (GTR)
    src = render(model, KernelOptions(real="float", vw=16))
    for name in im.NAMES:
        assert f"#define {name}(x) brdfcl_{name}(x)" in src and f"brdfcl_{name}(float16 x)" in src
    assert "brdfcl_" not in render(model, KernelOptions(real="double", vw=8))


@pytest.mark.parametrize("device", _devices())
@pytest.mark.parametrize("vw", [1, 16])
def test_device_functions_against_float64_and_the_twins(device, vw):
    real, cond = ("float", "int") if vw == 1 else (f"float{vw}", f"int{vw}")
    load = "x[i]" if vw == 1 else f"*(__global const {real} *)(x + {vw} * i)"
    store = "y[i]" if vw == 1 else f"*(__global {real} *)(y + {vw} * i)"
    src = im.c_source(real, cond) + "".join(f"""
__kernel void run_{name}(__global const float *x, __global float *y)
{{
    const int i = get_global_id(0);
    {store} = brdfcl_{name}({load});
}}
""" for name in im.NAMES)
    import pyopencl as cl

    from brdfcl.device.build import BUILD_OPTIONS
    from brdfcl.device.platforms import all_devices
    ctx = cl.Context([all_devices()[int(device)][1]])
    queue = cl.CommandQueue(ctx)
    prg = cl.Program(ctx, src).build(options=BUILD_OPTIONS)         # as the kernels are built
    for name in im.NAMES:
        x = np.concatenate([_inputs(name), SPECIAL])
        x = np.concatenate([x, np.ones(-len(x) % 16, np.float32)])
        y = np.empty_like(x)
        mf = cl.mem_flags
        xb = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=x)
        yb = cl.Buffer(ctx, mf.WRITE_ONLY, y.nbytes)
        getattr(prg, f"run_{name}")(queue, (len(x) // vw,), None, xb, yb)
        cl.enqueue_copy(queue, y, yb)
        body = x[: len(_inputs(name))]
        got = y[: len(body)]
        assert _ulps(got, body, name).max() <= MAX_ULP[name], name
        twin = im.TWINS[name](body)              # one rounding apart at most (FMA contraction may differ)
        assert (np.abs(got - twin) <= TWIN_ULP.get(name, 1.0) * np.spacing(np.abs(twin))).all(), name
        ok, vals = _special_ok(y[len(body): len(body) + len(SPECIAL)], name)
        assert ok, (name, vals)
