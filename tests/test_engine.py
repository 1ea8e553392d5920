"""OpenCL kernels against the float64 reference, on proxy data."""
import numpy as np
import pytest

from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import read_merl
from brdfcl.device.engine import Engine, select_cells
from brdfcl.model.compose import Model
from brdfcl.model.metrics import METRICS, errors, transform

SPECS = ["diffuse+diffraction+ggx",
         "diffuse+diffraction:abc:conductor+beckmann:smith-hc:dielectric",
         "diffraction:gauss:schlick+sgd:vcavity:conductor",
         "diffuse+epd:none:none", "ggx:smith-hc:none+diffraction:hp:dielectric",
         "beckmann:vcavity:schlick"]


@pytest.fixture(scope="module")
def tables(proxy_pair):
    return [read_merl(p) for p in proxy_pair]


def _random_values(model, rng, n):
    return model.from_x(model.x_lo + rng.random((n, model.n_free)) * (model.x_hi - model.x_lo))


def _reference(model, cells, meas, w, values, metric):
    p, J = model.reference(cells, values)
    cw = cells.ci
    ok = np.isfinite(meas)
    gp, dg = transform(metric, p * cw)
    r = np.where(ok, gp - transform(metric, np.where(ok, meas, 0) * cw)[0], 0)
    ww = np.where(ok, w, 0)
    u = np.where(ok[..., None], (dg * cw)[..., None] * J, 0)
    return p, np.sum(ww * r * r), 2 * np.einsum("cn,cnk->k", ww * r, u), np.einsum("cn,cnk,cnl->kl", ww, u, u)


@pytest.mark.parametrize("real, tol", [pytest.param("double", 1e-10, marks=pytest.mark.slow), ("float", 1e-5)])
@pytest.mark.parametrize("spec", SPECS)
def test_kernels_match_reference(tables, spec, real, tol):
    _match_reference(tables, spec, real, tol)


@pytest.mark.parametrize("spec, fixed", [
    (SPECS[0], {}), (SPECS[1], {}), (SPECS[1], {f"diffraction.k_{c}": 2.0 for c in "rgb"}),
    (SPECS[4], {"diffraction.eta": 1.5})])
def test_kernels_with_a_loop_over_channels_match_reference(tables, spec, fixed):
    """The kernels written as one loop over the channels (as for many-band spectral models)
    compute what the unrolled ones do: per-channel columns, shared ones and their J^T J."""
    _match_reference(tables, spec, "float", 1e-5, channel_loop=True, fixed=fixed)


def _match_reference(tables, spec, real, tol, fixed=None, **options):
    rng = np.random.default_rng(len(spec))
    full = spec == SPECS[0]
    idx = select_cells(90 if full else 80)[:: 1 if full else 13]     # all valid cells for the full model
    metric = METRICS[len(spec) % 3]
    eng = Engine(Model(spec, fixed=fixed), real=real, metric=metric, **options)
    cs = eng.cellset(tables, idx)
    cells = cs.cells()
    w = table_geometry().weight[idx]
    V = _random_values(eng.model, rng, 2 if full else 4)
    mats = np.arange(len(V)) % 2
    P = eng.predict(cs, V)
    L, G = eng.grad(cs, V, mats)
    L2, JTr, H = eng.jtj(cs, V, mats)
    E = eng.errors(cs, V, mats)
    for e in range(len(V)):
        meas = tables[mats[e]].brdf()[:, idx]
        p, lr, gr, hr = _reference(eng.model, cells, meas, w, V[e], metric)
        big = np.abs(p) > 1e-6 * np.abs(p).max()
        np.testing.assert_allclose(P[e][big], p[big], rtol=tol * 10)       # per cell
        assert L[e] == pytest.approx(lr, rel=tol) and L2[e] == pytest.approx(lr, rel=tol)
        gscale = np.abs(gr).max()
        np.testing.assert_allclose(G[e], gr, rtol=tol, atol=tol * gscale)
        np.testing.assert_allclose(2 * JTr[e], gr, rtol=tol, atol=tol * gscale)
        np.testing.assert_allclose(H[e], hr, rtol=tol, atol=tol * np.abs(hr).max())
        ref_err = errors(p, meas, w, cells.ci)
        for k, v in ref_err.items():
            assert E[k][e] == pytest.approx(v, rel=tol), k


@pytest.mark.slow
@pytest.mark.parametrize("real", ["float", "double"])
def test_no_nan_at_extremes(tables, real):
    """Bounds, alpha at 1e-4, a at both bounds, zero amplitudes, grazing cells included."""
    for spec in ("diffuse+diffraction:abc:conductor+ggx:smith:schlick", "diffraction:gauss:dielectric+beckmann",
                 "diffuse+diffraction+sgd", "diffraction:hp+epd:smith-hc:schlick".replace(":smith-hc", ":none"),
                 "ggx:smith-hc:conductor"):
        eng = Engine(spec, real=real)
        m = eng.model
        cs = eng.cellset(tables, select_cells(None))
        corners = [m.lo, m.hi, m.defaults()]
        rng = np.random.default_rng(3)
        corners += list(np.where(rng.random((12, m.n_params)) < 0.5, m.lo, m.hi))
        zero = m.defaults()
        zero[m.amplitude] = 0.0
        corners.append(zero)
        V = np.array(corners)
        mats = np.arange(len(V)) % 2
        L, Jr, H = eng.jtj(cs, V, mats)
        _, G = eng.grad(cs, V, mats)
        E = eng.errors(cs, V, mats)
        assert np.isfinite(L).all() and np.isfinite(Jr).all() and np.isfinite(H).all(), spec
        assert np.isfinite(G).all() and all(np.isfinite(v).all() for v in E.values()), spec
        assert np.isfinite(eng.predict(cs, V)).all(), spec


def test_float32_accumulation_over_the_whole_table(tables):
    """The sum of 1.4 million float32 weights keeps float64 precision (bounded partial sums)."""
    eng = Engine("diffuse", real="float", metric="l2", cosw=False)
    g = table_geometry()
    idx = np.flatnonzero(g.above_horizon)
    cs = eng.cellset(tables[:1], idx)
    ok = tables[0].valid[idx]
    exact = 3 * np.sum(g.weight[idx][ok].astype(np.float32).astype(np.float64))
    got = eng._run("errors", cs, eng.model.defaults()[None], [0])[0, 4]     # sum of w over channels
    assert got == pytest.approx(exact, rel=1e-6)


def test_blocks_give_the_same_answer(tables):
    eng = Engine("diffuse+ggx", real="double")
    idx = select_cells()[::11]
    one = eng.cellset(tables, idx)
    split = eng.cellset(tables, idx, max_alloc=3 * one.n_cells * 8)
    assert len(one.blocks) == 1 and len(split.blocks) == 2
    V = np.tile(eng.model.defaults(), (4, 1))
    mats = [1, 0, 1, 0]
    np.testing.assert_allclose(eng.jtj(one, V, mats)[2], eng.jtj(split, V, mats)[2], rtol=1e-14)


def test_device_selection():
    """An index picks that device; ``cpu`` a CPU device (the preferred one, not index 0 where
    several CPU runtimes build: pip's PoCL and Intel's on an Intel CPU)."""
    from brdfcl.device.platforms import DeviceError, all_devices, is_cpu, pick_device
    p, d = pick_device("0")
    assert d.int_ptr == all_devices()[0][1].int_ptr
    assert is_cpu(pick_device("cpu")[1])
    with pytest.raises(DeviceError, match="no OpenCL device"):
        pick_device("no-such-gpu")


def test_many_channels_share_one_loop_unless_their_parameters_differ_in_kind():
    """From LOOP_FROM channels on, a program is one loop over its channels (its size does not
    grow with their number); a per-channel parameter fixed in some channels and free in others
    cannot share a body, and that model is written channel by channel."""
    from brdfcl.kernels.codegen import LOOP_FROM, KernelOptions, render
    from brdfcl.model.lobes.lobe import NotLoopable

    def model(n, fixed=None):
        return Model(SPECS[1], fixed=fixed, lambdas=tuple(0.40 + 0.01 * i for i in range(n)))

    size = {n: len(render(model(n), KernelOptions())) for n in (LOOP_FROM, 31)}
    assert "one loop over the 31 channels" in render(model(31), KernelOptions())
    assert size[31] < 1.5 * size[LOOP_FROM]                # the slot loads grow, not the code
    assert "written out one by one" in render(model(3), KernelOptions())
    mixed = model(31, {"diffraction.k_400nm": 2.0})
    assert "written out one by one" in render(mixed, KernelOptions())
    with pytest.raises(NotLoopable, match="diffraction.k_400nm"):
        render(mixed, KernelOptions(channel_loop=True))


def test_owned_data_is_read_in_place_and_a_callers_is_copied():
    """On a CPU device a cell set reads data it owns (``own``: the pipeline's arrays, or its own
    padded copy) in place and makes them read-only; a caller's array is copied and stays theirs."""
    from brdfcl.data.geometry import TABLE
    from brdfcl.device.cellsets import Place, aligned_empty
    from brdfcl.device.platforms import is_cpu
    try:
        engine = Engine("diffuse")
    except Exception as e:          # noqa: BLE001 - no device builds here
        pytest.skip(f"no OpenCL device: {e}")
    idx = select_cells(80.0, stride=50)[:1024]           # a multiple of every vector width
    rng = np.random.default_rng(5)
    values = rng.uniform(0.05, 0.5, (2, 3, idx.size)).astype(np.float32)
    v = engine.model.defaults()
    mats = np.array([0, 1])
    want = engine.loss(engine.upload(["a", "b"], idx, values.copy()), [v, v], mats)

    theirs = values.copy()
    cs = engine.upload(["a", "b"], idx, theirs)
    assert theirs.flags.writeable
    theirs[:] = 1.0                                       # the caller's to change: the set keeps its copy
    np.testing.assert_array_equal(engine.loss(cs, [v, v], mats), want)

    owned = aligned_empty(values.shape, np.float32)
    owned[:] = values
    cs = engine.upload_places(["a", "b"], [Place(TABLE, idx, 1.0)], owned, own=True)
    np.testing.assert_array_equal(engine.loss(cs, [v, v], mats), want)
    assert owned.flags.writeable is (not is_cpu(engine.device))
    if is_cpu(engine.device):
        with pytest.raises(ValueError):
            owned[0, 0, 0] = 2.0
