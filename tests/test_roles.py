"""Lobe roles and repeated lobe kinds: ``diffuse+ggx+ggx`` (a narrow and a broad specular lobe), and
analysis, selection and the peak constraint asking for lobes by role, wherever they stand."""
import csv
import json

import numpy as np
import pytest

from brdfcl.analysis.analyze import lobe_images, peak_share
from brdfcl.app.run import fit_all
from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import read_merl, write_merl
from brdfcl.device.engine import Engine, select_cells
from brdfcl.kernels.codegen import KernelOptions, emit, jtj_pairs, render
from brdfcl.model.compose import Model, ModelError
from brdfcl.model.lobes import CookTorrance, Diffraction, Diffuse
from brdfcl.model.lobes.lobe import ROLES
from brdfcl.model.synth import demo_values, tabulate
from brdfcl.optim.peak_order import PeakOrder
from brdfcl.optim.selection import variants
from tests.test_engine import _random_values, _reference
from tests.test_peak_order import assert_residual_jacobian
from tests.test_reference import random_cells

TWO = "diffuse+ggx+ggx"
TRUTH = {"diffuse.rho": (0.05, 0.04, 0.03), "ct.rho": (0.6, 0.5, 0.4), "ct.alpha": 0.03,
         "ct.F0": (0.9, 0.8, 0.6), "ct2.rho": (0.4, 0.35, 0.3), "ct2.alpha": 0.3,
         "ct2.F0": (0.3, 0.3, 0.3)}


def test_roles_are_declared_by_the_lobe_classes():
    assert (Diffuse.role, Diffraction.role, CookTorrance.role) == ("diffuse", "diffraction", "reflection")
    assert set(ROLES) == {"diffuse", "diffraction", "reflection"}
    m = Model("ggx+diffraction+diffuse+beckmann")
    assert [lb.prefix for lb in m.lobes_with_role("reflection")] == ["ct", "ct2"]
    assert m.prefixes_with_role("diffuse", "diffraction") == ("diffuse", "diffraction")
    with pytest.raises(ValueError):
        m.lobes_with_role("ct")


def test_repeated_kinds_get_numbered_prefixes_and_single_lobes_keep_theirs():
    assert Model().names[:4] == ["diffuse.rho_r", "diffuse.rho_g", "diffuse.rho_b", "diffraction.rho_r"]
    assert "ct.alpha" in Model().names and "diffraction.a" in Model().names
    m = Model(TWO)
    assert [lb.prefix for lb in m.lobes] == ["diffuse", "ct", "ct2"]
    assert {"ct.alpha", "ct2.alpha", "ct2.rho_g", "ct2.F0_b"} <= set(m.names)
    assert len(set(m.names)) == len(m.names) and len(set(s.cname for s in m.slots)) == m.n_params
    m3 = Model("diffraction+diffraction:abc+diffuse+diffuse+ggx+ggx+sgd")
    assert [lb.prefix for lb in m3.lobes] == ["diffraction", "diffraction2", "diffuse", "diffuse2",
                                              "ct", "ct2", "ct3"]
    assert "diffraction2.c" in m3.names and "ct3.p" in m3.names and len(set(m3.names)) == m3.n_params
    assert Model(m.spec).names == m.names                    # the spec round-trips
    f = Model(TWO, fixed={"ct2.alpha": 0.3})
    assert f.n_free == m.n_free - 1 and f.defaults()[f.names.index("ct2.alpha")] == 0.3
    with pytest.raises(ModelError):
        Model("diffuse+ggx", fixed={"ct2.alpha": 0.3})


def test_generated_c_names_are_unique():
    """Each C name the lobes declare is declared once, two lobes of one kind included."""
    for spec in (TWO, "diffraction+diffraction:abc:schlick+ggx+sgd+sgd:vcavity:dielectric+diffuse+diffuse"):
        for m in (Model(spec), Model(spec, fixed={"ct2.alpha": 0.2})):
            names = []
            for ln in emit(m).lines:
                decl = ln.split("=")[0] if "=" in ln else ln.rstrip(";")
                words = decl.replace(",", " ").split()
                names += [w for w in words if w not in ("const", "real", "real_v")]
            assert len(names) == len(set(names)), [n for n in names if names.count(n) > 1]
            assert any(n.startswith("ct2_") for n in names)
            assert any(n.startswith("diffraction2_") for n in names) == ("diffraction" in spec)
            src = render(m, KernelOptions())
            assert "P_ct2_alpha" in src and ("P_diffraction2_c" in src) == ("diffraction" in spec)
            assert len(jtj_pairs(m)) == len(set(jtj_pairs(m)))


@pytest.mark.parametrize("real, tol", [("double", 1e-10), ("float", 1e-5)])
@pytest.mark.parametrize("spec, fixed", [(TWO, {}), (TWO, {"ct2.alpha": 0.3}),
                                         ("diffraction:abc+diffuse+ggx+diffraction+beckmann", {})])
def test_kernels_match_reference(proxy_pair, spec, fixed, real, tol):
    tables = [read_merl(p) for p in proxy_pair]
    rng = np.random.default_rng(7)
    idx = select_cells(80)[::13]
    eng = Engine(Model(spec, fixed=fixed), real=real, metric="log")
    assert eng.model.fixed == fixed
    cs = eng.cellset(tables, idx)
    cells = cs.cells()
    w = table_geometry().weight[idx]
    V = _random_values(eng.model, rng, 4)
    mats = np.arange(len(V)) % 2
    P = eng.predict(cs, V)
    L, G = eng.grad(cs, V, mats)
    L2, JTr, H = eng.jtj(cs, V, mats)
    for e in range(len(V)):
        meas = tables[mats[e]].brdf()[:, idx]
        p, lr, gr, hr = _reference(eng.model, cells, meas, w, V[e], "log")
        big = np.abs(p) > 1e-6 * np.abs(p).max()
        np.testing.assert_allclose(P[e][big], p[big], rtol=tol * 10)
        assert L[e] == pytest.approx(lr, rel=tol) and L2[e] == pytest.approx(lr, rel=tol)
        gscale = np.abs(gr).max()
        np.testing.assert_allclose(G[e], gr, rtol=tol, atol=tol * gscale)
        np.testing.assert_allclose(2 * JTr[e], gr, rtol=tol, atol=tol * gscale)
        np.testing.assert_allclose(H[e], hr, rtol=tol, atol=tol * np.abs(hr).max())


def test_jacobian_matches_finite_differences():
    m = Model(TWO)
    rng = np.random.default_rng(5)
    cells = random_cells(rng, 60)
    for v in _random_values(m, rng, 6):
        p, J = m.reference(cells, v)
        for k, i in enumerate(m.free_index):
            h = 1e-6 * max(abs(v[i]), 1e-3)
            vp, vm = v.copy(), v.copy()
            vp[i] += h
            vm[i] -= h
            fd = (m.reference(cells, vp, jacobian=False) - m.reference(cells, vm, jacobian=False)) / (2 * h)
            tol = 1e-5 * np.abs(fd) + 1e-7 * np.abs(J[:, :, k]).max() + 1e-13 * np.abs(p) / h   # + rounding
            assert np.all(np.abs(J[:, :, k] - fd) <= tol), m.names[i]
    # the two CT lobes are the same function of their own parameters
    one = Model("ggx")
    v = m.defaults()
    v[m.names.index("ct.alpha")], v[m.names.index("ct2.alpha")] = 0.05, 0.4
    lobe2 = m.submodel(m.lobes[2:])
    assert lobe2.names == [n for n in m.names if n.startswith("ct2.")]
    vals = v[[m.names.index(n) for n in lobe2.names]]
    np.testing.assert_array_equal(lobe2.reference(cells, vals, jacobian=False),
                                  one.reference(cells, vals, jacobian=False))


def _order_by_alpha(params):
    """(narrow, broad) prefix of the two CT lobes of a fit."""
    return tuple(sorted(("ct", "ct2"), key=lambda p: params[f"{p}.alpha"]))


def test_fit_recovers_a_narrow_and_a_broad_ggx_lobe(tmp_path):
    m = Model(TWO)
    truth = m.as_dict(demo_values(m, TRUTH))
    src = tmp_path / "data"
    src.mkdir()
    write_merl(src / "two-lobes.binary", tabulate(m, demo_values(m, TRUTH)))
    out = tmp_path / "out"
    rep = fit_all(src, out, model=TWO)
    (r,) = rep.results
    assert r.success, r.status
    narrow, broad = _order_by_alpha(r.params)
    for fit_p, true_p in ((narrow, "ct"), (broad, "ct2")):
        assert r.params[f"{fit_p}.alpha"] == pytest.approx(truth[f"{true_p}.alpha"], rel=0.03), fit_p
        for c in "rgb":
            assert r.params[f"{fit_p}.rho_{c}"] == pytest.approx(truth[f"{true_p}.rho_{c}"], rel=0.05)
    assert r.errors["rmse_log"] < 1e-3
    # the parameter names carry through the outputs
    doc = json.loads((out / "two-lobes.json").read_text())
    assert {"ct.alpha", "ct2.alpha", "ct2.F0_b"} <= set(doc["params"])
    row = next(csv.DictReader(open(out / "summary.csv")))
    assert {"ct.alpha", "ct2.alpha", "ct2.rho_r"} <= set(row)


def test_selection_drops_lobes_by_role():
    assert variants("diffuse+diffraction+ggx") == {"full": "diffuse+diffraction+ggx", "no_diffraction": "diffuse+ggx",
                                                   "no_ct": "diffuse+diffraction"}
    v = variants("diffraction:abc+ggx+diffuse+diffraction+beckmann")
    assert v == {"full": "diffraction:abc+ggx+diffuse+diffraction+beckmann", "no_diffraction": "ggx+diffuse+beckmann",
                 "no_ct": "diffraction:abc+diffuse+diffraction"}
    assert variants(TWO) == {"full": TWO, "no_ct": "diffuse"}
    assert variants("ggx+ggx") == {"full": "ggx+ggx"}
    # the variants keep the remaining lobes' parameter names
    full = Model("diffraction+ggx+diffuse+diffraction:gauss+beckmann")
    for spec in variants(full.spec).values():
        assert set(Model(spec).names) <= set(full.names)


def test_peak_constraint_and_analysis_ask_roles():
    m = Model("ggx+diffraction+diffuse+diffraction:gauss+beckmann")
    po = PeakOrder.for_model(m)
    assert [lb.prefix for lb in po.w.lobes] == ["diffraction", "diffraction2"]
    assert [lb.prefix for lb in po.c.lobes] == ["ct", "ct2"]
    assert PeakOrder.for_model(Model("diffraction+diffuse")) is None
    assert PeakOrder.for_model(Model("ggx+diffuse+ggx")) is None
    # the penalty's Jacobian over all lobes of both roles
    rng = np.random.default_rng(2)
    V = np.tile(m.defaults(), (4, 1))
    for n in m.names:
        if n.startswith("diffraction") and ".rho" in n:
            V[:, m.names.index(n)] *= rng.uniform(10, 100, 4)
    scale = np.ones(4)
    r, J = po.residual(V, scale)
    assert (r > 0).sum() >= 4
    assert_residual_jacobian(po, m, V, scale, J)
    # with one lobe of each role listed in any order, the same numbers as the usual order
    a, b = Model("diffuse+diffraction+ggx"), Model("ggx+diffraction+diffuse")
    va = a.defaults()
    va[a.names.index("diffraction.rho_g")] = 5.0
    pa = a.as_dict(va)
    share_a = peak_share(a.spec, pa)
    assert share_a > 0 and share_a == pytest.approx(peak_share(b.spec, pa), rel=1e-12)
    assert po.excess(V).shape == (4, 3)
    share = peak_share(m.spec, m.as_dict(V[0]))
    assert 0 < share < 1
    img_a, img_b = lobe_images(a.spec, pa), lobe_images(b.spec, pa)
    for k in ("diffuse_diffraction", "ct", "full"):
        np.testing.assert_allclose(img_a[k], img_b[k], rtol=1e-12, equal_nan=True)
