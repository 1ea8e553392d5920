"""Every registered term, found in the registry (no hand-written list): a newly registered D, G, F
or PSD is tested by registering it.  For each, a model that uses it must (1) have a Jacobian that
matches central finite differences of its float64 reference, and (2) compile into kernels whose
every output matches that reference (brdfcl.device.selftest, float64)."""
import zlib

import numpy as np
import pytest

from brdfcl.data.geometry import table_geometry
from brdfcl.device import selftest
from brdfcl.device.engine import Engine
from brdfcl.model.compose import CT_NDFS, Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.terms import REGISTRY, shadowing_for


def spec_for(kind, name):
    """The smallest model string that uses a registered term."""
    if kind == "ndf":
        return f"{name}:vcavity:schlick"
    if kind == "fresnel":
        return f"ggx:smith:{name}"
    if kind == "psd":
        return f"diffraction:{name}:schlick"
    term = REGISTRY["shadowing"][name]                             # shadowing: its family's word
    for ndf in term.ndfs or CT_NDFS:
        if shadowing_for(ndf, term.family) is term:
            return f"{ndf}:{term.family}:none"
    raise AssertionError(f"no model string uses the {kind} term {name}")


TERMS = [(kind, name) for kind, terms in REGISTRY.items() for name in terms]


@pytest.mark.parametrize("kind, name", TERMS, ids=[f"{k}-{n}" for k, n in TERMS])
def test_term_jacobian_matches_finite_differences(kind, name):
    spec = spec_for(kind, name)
    model = Model(spec)
    assert name in model.spec.replace("-", "_") or kind == "shadowing"
    rng = np.random.default_rng(zlib.crc32(spec.encode()))
    g = table_geometry()
    cells = Cells.from_geometry(g, rng.choice(np.flatnonzero(g.mask(80.0)), 30, replace=False))
    for _ in range(3):
        x = model.x_lo + (0.2 + 0.6 * rng.random(model.n_free)) * (model.x_hi - model.x_lo)
        v = model.from_x(x)
        _, J = model.reference(cells, v)
        for k, i in enumerate(model.free_index):
            h = 1e-6 * max(abs(v[i]), 1e-3)
            vp, vm = v.copy(), v.copy()
            vp[i] += h
            vm[i] -= h
            fd = (model.reference(cells, vp, False) - model.reference(cells, vm, False)) / (2 * h)
            scale = np.abs(fd).max() + np.abs(J[..., k]).max() + 1e-300
            assert np.abs(J[..., k] - fd).max() <= 1e-5 * scale, (spec, model.names[i])


@pytest.mark.parametrize("kind, name", TERMS, ids=[f"{k}-{n}" for k, n in TERMS])
def test_term_kernels_match_the_reference(kind, name):
    res = selftest.check(Engine(spec_for(kind, name), real="double", verify=False))
    assert res.ok, res.detail
