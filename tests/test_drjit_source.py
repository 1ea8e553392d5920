"""Every term's formula printed as Dr.Jit Python (brdfcl.report.export.drjit_source) computes what
its float64 reference does.

The printed functions call only ``dr.*`` (and the helpers printed with them), so they are run
twice: on numpy arrays through a stand-in for ``dr`` (no Dr.Jit needed: the printer's output is
checked wherever the tests run), and, where Dr.Jit's LLVM backend is usable, on its float32 arrays."""
import types

import numpy as np
import pytest

from brdfcl.model.lobes.cells import Cells
from brdfcl.model.terms import REGISTRY
from brdfcl.report.export import drjit_source as ds

TERMS = [t for kind in REGISTRY.values() for t in kind.values()]

NUMPY_DR = types.SimpleNamespace(
    exp=np.exp, log=np.log, sqrt=np.sqrt, rsqrt=lambda x: 1.0 / np.sqrt(x), abs=np.abs, power=np.power,
    minimum=np.minimum, maximum=np.maximum, select=np.where)


def _compile(source, name, dr):
    ns = {"dr": dr}
    exec(ds.HELPERS, ns)
    exec(source, ns)
    return ns[name]


def _cells(n=500, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2]) + 0.05
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return Cells.from_directions(v[0], v[1])


def _inputs(term):
    """Each input at a value inside its parameter's range (a ``uses`` input: an alpha of 0.2)."""
    out = {p.name: float(np.clip(p.default * 1.1, p.lo, p.hi)) for p in term.params}
    out.update({u: 0.2 for u in term.uses})
    return out


def _args(term, cells, freq, inputs, consts):
    names = ds.term_args(term)
    return [freq if a == "f" else inputs[a] if a in inputs else consts[a] if a in consts else getattr(cells, a)
            for a in names]


@pytest.mark.parametrize("term", TERMS, ids=lambda t: f"{t.kind}-{t.name}")
def test_printed_term_matches_its_reference_in_float64(term):
    cells, freq = _cells(), np.geomspace(1e-3, 1e2, 500)
    inputs = _inputs(term)
    consts = term.consts(**inputs)
    ref, _ = term.reference(freq if term.arg == "f" else cells, **inputs, **consts)
    source = ds.term_source(term)
    fn = _compile(source, "value", NUMPY_DR)
    with np.errstate(all="ignore"):
        got = np.broadcast_to(fn(*_args(term, cells, freq, inputs, consts)), ref.shape)
    # the printed erfc is Numerical Recipes' fit (relative error < 1.2e-7), scipy's is exact;
    # below 1e-300 only denormals differ
    rtol = 5e-7 if "_erfc(" in source else 1e-11
    np.testing.assert_allclose(got, ref, rtol=rtol, atol=1e-300)


def test_printed_cell_quantities_match_the_reference_cells():
    c = _cells()
    derived = _compile(ds.cell_source(), "derived", NUMPY_DR)(c.sh, c.ch, c.cd, c.ci, c.co)
    for name, value in derived.items():
        np.testing.assert_allclose(value, getattr(c, name), rtol=1e-12, err_msg=name)


def test_erfc_and_log1p_helpers_are_accurate():
    from scipy.special import erfc
    ns = {"dr": NUMPY_DR}
    exec(ds.HELPERS, ns)
    x = np.linspace(-4, 6, 2001)
    np.testing.assert_allclose(ns["_erfc"](x), erfc(x), rtol=1.2e-7)
    y = np.geomspace(1e-12, 10, 500)
    np.testing.assert_allclose(ns["_log1p"](y), np.log1p(y), rtol=1e-15)


@pytest.fixture(scope="module")
def llvm_float():
    dr = pytest.importorskip("drjit", reason='Dr.Jit not installed: pip install "brdfcl[mitsuba]"')
    try:
        from drjit.llvm import Float
        have = tuple(dr.detail.llvm_version())
    except Exception as e:
        pytest.skip(f"Dr.Jit's LLVM backend is unavailable here: {e}")
    if have < (17,):
        pytest.skip(f"Dr.Jit loaded libLLVM {have}, too old for its kernels (Debian 12: apt install libllvm19)")
    return dr, Float


@pytest.mark.parametrize("term", TERMS, ids=lambda t: f"{t.kind}-{t.name}")
def test_printed_term_runs_in_drjit_float32(llvm_float, term):
    dr, Float = llvm_float
    cells, freq = _cells(), np.geomspace(1e-3, 1e2, 500)
    inputs = _inputs(term)
    consts = term.consts(**inputs)
    ref, _ = term.reference(freq if term.arg == "f" else cells, **inputs, **consts)
    fn = _compile(ds.term_source(term), "value", dr)
    args = [Float(a.astype(np.float32)) if isinstance(a, np.ndarray) else a
            for a in _args(term, cells, freq, inputs, consts)]
    got = np.broadcast_to(np.array(fn(*args) * Float(np.ones(500, np.float32)), dtype=np.float64), ref.shape)
    ok = np.abs(ref) > 1e-30
    rel = np.abs(got[ok] - ref[ok]) / np.abs(ref[ok])
    assert np.median(rel) < 1e-5 and rel.max() < 1e-3, (np.median(rel), rel.max())
