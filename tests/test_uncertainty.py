"""Standard errors, directional albedo and flags of a fit (brdfcl.optim.uncertainty).

The standard errors are checked against a bootstrap over cells: RESAMPLES multinomial resamples of
the fitted cells, each refitted from the optimum by Levenberg-Marquardt with the counts as weights.
The bootstrap spread of a parameter is itself known to about 1/sqrt(2 (B - 1)) = 7% (B = 100), so
the band RATIO is about +-4 of those standard deviations.  Measured (this test, the middle term
summed by the kernel over every fitted cell, float32 PoCL, 2 cores): 0.89 to 0.98 per parameter;
earlier, with the middle term summed by the float64 reference on every 46th cell of the full table
(60 resamples), 0.90-1.09 for this material and 0.83-1.17 for synth-mirror (alpha 1e-3); for
synth-smooth-metal with the three-lobe model (14 parameters) 0.90-1.02.  The homoscedastic
sigma^2 H^-1 (J^T W^2 J) H^-1 gives 0.07 for the specular parameters of such a material."""
import json
import time

import numpy as np
import pytest

from brdfcl.data.geometry import TableLayout, coarse_cells, table_geometry
from brdfcl.data.measurement import Measurement, rgb_channels
from brdfcl.device.engine import Engine, select_cells
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.synth import DEMO, demo_values
from brdfcl.optim.albedo import ALBEDO_LIMIT, directional_albedo
from brdfcl.optim.assessment import bounds_hit, flags
from brdfcl.optim.fit import FitOptions, Fitter
from brdfcl.optim.lm import LMOptions, levenberg_marquardt
from brdfcl.optim.objective import Target, penalty_scale
from brdfcl.report.output import result_document

MATERIAL = "synth-smooth-plastic"   # diffuse+ggx:smith:dielectric, alpha 0.03
NOISE = 0.02                        # multiplicative, as `brdfcl synth --noise 0.02`
CELL_STRIDE = 16                    # every 16th fitted cell (57k cells) keeps the test fast
RESAMPLES = 100
RATIO = (0.7, 1.4)


def _noisy_table(model, values, index, noise, seed):
    """Values of the model at the cells with multiplicative noise, as brdfcl.model.synth.write_synth."""
    rng = np.random.default_rng(seed)
    p = model.reference(Cells.from_geometry(table_geometry(), index), values, jacobian=False)
    return np.maximum(p * (1.0 + noise * rng.standard_normal(p.shape)), 0.0)


class _Strided(TableLayout):
    """The table's fitted cells, every CELL_STRIDE-th; the coarse set every 8th of those."""

    def select(self, cutoff_deg=80.0):
        return select_cells(cutoff_deg, stride=CELL_STRIDE, offset=5)

    def coarse(self, index, stride, peak_bins, peak_stride):
        return coarse_cells(index, 8, peak_bins, 1)


class _Values(Measurement):
    """A synthetic table known at the strided cells only."""

    channels = rgb_channels()

    def __init__(self, name, layout, values):
        self.name, self.path, self._layout, self.values = name, None, layout, values
        self._pos = {int(i): k for k, i in enumerate(layout.select())}

    @property
    def layout(self):
        return self._layout

    def values_at(self, indices, outs):
        for o, idx in zip(outs, indices):
            o[...] = self.values[:, [self._pos[int(i)] for i in idx]]


def _bootstrap(fitter, names, data, x_fit, resamples, seed):
    """Refits over resamples of the cells (multinomial counts as weights), a few LM iterations each
    from the optimum: (resamples, free parameters) natural values."""
    eng, m, sp = fitter.engine, fitter.model, fitter.objective.spaces
    idx = _Strided().select(fitter.opts.cutoff_deg)
    rng = np.random.default_rng(seed)
    ylo, yhi = sp.y_bounds
    out = []
    for _ in range(resamples):
        counts = rng.multinomial(idx.size, np.full(idx.size, 1.0 / idx.size)).astype(float)
        target = Target(eng.upload(names, idx, data, weight_scale=counts), penalty_scale(idx, data))
        st = levenberg_marquardt(lambda ys, rows: fitter.objective.jtj(target, ys, rows), sp.to_y(x_fit[None]),
                                 ylo, yhi, LMOptions(max_iter=8))
        out.append(m.from_x(sp.from_y(st.x))[0, m.free_index])
    return np.array(out)


def test_standard_errors_match_bootstrap():
    spec, params = DEMO[MATERIAL]
    opts = FitOptions(model=spec)
    f = Fitter(opts)
    m = f.model
    layout = _Strided()
    truth = demo_values(m, params)
    full = _noisy_table(m, truth, layout.select(opts.cutoff_deg), NOISE, seed=1)[None].astype(np.float32)
    t = time.perf_counter()
    (res,) = f.fit([_Values(MATERIAL, layout, full[0])])
    t_fit = time.perf_counter() - t
    assert res.success and not res.bounds_hit, (res.status, res.bounds_hit)
    unc = res.uncertainty
    se = np.array([unc["std_error"][m.names[i]] for i in m.free_index])
    assert np.all(se > 0)

    x_fit = m.to_x(np.array([res.params[n] for n in m.names]))
    t = time.perf_counter()
    boot = _bootstrap(f, [MATERIAL], full, x_fit, RESAMPLES, seed=2)
    t_boot = time.perf_counter() - t
    spread = boot.std(axis=0, ddof=1)
    ratio = se / spread
    report = {m.names[i]: round(float(r), 2) for i, r in zip(m.free_index, ratio)}
    print(f"\nstd_error / bootstrap spread ({RESAMPLES} resamples): {report}; fit {t_fit:.1f} s "
          f"(uncertainty {res.stages.get('uncertainty', 0):.2f} s), bootstrap {t_boot:.1f} s")
    assert np.all((ratio > RATIO[0]) & (ratio < RATIO[1])), report
    # the correlation matches the bootstrap's too, where it is strong
    names = unc["correlation"]["names"]
    C = np.array(unc["correlation"]["matrix"])
    Cb = np.corrcoef(boot.T)
    cols = [list(m.names[i] for i in m.free_index).index(n) for n in names]
    strong = np.abs(Cb[np.ix_(cols, cols)]) > 0.5
    assert np.all(np.abs(C - Cb[np.ix_(cols, cols)])[strong] < 0.25)

    doc = json.loads(json.dumps(result_document(res, m), allow_nan=False))
    assert set(doc["uncertainty"]) == {"std_error", "correlation", "method"}
    assert set(doc["uncertainty"]["correlation"]) == {"names", "matrix"}
    assert doc["albedo"]["theta_i_deg"] == [0.0, 30.0, 60.0, 75.0, 85.0]
    assert np.shape(doc["albedo"]["channels"]) == (5, 3)
    assert isinstance(doc["flags"], list)


def test_albedo_known_cases():
    lam = Model("diffuse")
    rho = np.array([0.2, 0.5, 0.9])
    a = directional_albedo(lam, demo_values(lam, {"diffuse.rho": tuple(rho)}))[0]
    np.testing.assert_allclose(a, np.broadcast_to(rho, a.shape), atol=1e-3)
    ggx = Model("ggx:smith:schlick")                     # F0 = 1: F = 1 at every angle
    narrow = demo_values(ggx, {"ct.rho": (1, 1, 1), "ct.alpha": 1e-3, "ct.F0": (1, 1, 1)})
    a = directional_albedo(ggx, narrow)[0]
    assert np.all(a <= 1 + 1e-4) and np.all(a[0] > 0.999), a


def test_flags_fire_on_non_physical_fit():
    m = Model("diffuse+ggx:smith:schlick")
    good = demo_values(m, {"diffuse.rho": (0.3, 0.3, 0.3), "ct.rho": (0.5, 0.5, 0.5), "ct.alpha": 0.1,
                           "ct.F0": (0.9, 0.9, 0.9)})
    assert flags(m, good, bounds_hit(m, m.to_x(good)), None, directional_albedo(m, good)[0]) == []
    bad = demo_values(m, {"diffuse.rho": (0.9, 0.2, 0.2), "ct.rho": (1.0, 0.5, 0.5), "ct.alpha": 1e-4,
                          "ct.F0": (0.9, 0.9, 0.9)})
    alb = directional_albedo(m, bad)[0]
    assert alb[:, 0].max() > ALBEDO_LIMIT
    hit = bounds_hit(m, m.to_x(bad))
    assert hit == ["ct.alpha"]
    lines = flags(m, bad, hit, None, alb)
    assert len(lines) == 2
    assert "albedo above 1" in lines[0] and "channel r" in lines[0]
    assert lines[1].startswith("ct.alpha = 0.0001 at its lower bound")


def test_lobes_that_trade_places_are_flagged_where_both_give_a_share():
    """Two lobes' amplitudes correlated beyond TRADE_LIMIT in a channel: one line naming the lobes
    and channels, unless one of them gives under TRADE_SHARE of their albedo there."""
    from brdfcl.optim.assessment import TRADE_LIMIT, TRADE_SHARE, traded, trades
    from brdfcl.optim.uncertainty import Uncertainty
    m = Model("diffuse+diffraction+ggx:smith:schlick")
    names = [n for n in m.names if n != "diffraction.a"]
    corr = np.eye(len(names))
    for c, r in zip("rgb", (-1.0, -0.995, -0.5)):
        i, j = names.index(f"diffuse.rho_{c}"), names.index(f"diffraction.rho_{c}")
        corr[i, j] = corr[j, i] = r
    unc = Uncertainty({n: 0.01 for n in names}, names, corr, "test")
    assert -0.995 < -TRADE_LIMIT
    (line,) = trades(m, unc)
    assert line.startswith("lobes diffraction and diffuse trade places in channels r, g (amplitude "
                           "correlation -1.000 in r)")
    both = {"diffuse": np.full((1, 3), 0.3), "diffraction": np.full((1, 3), 0.1), "ct": np.full((1, 3), 0.5)}
    assert len(trades(m, unc, both)) == 1
    assert traded(["ct.alpha = 0.0001 at its lower bound", line]) == [("diffraction", "diffuse")]
    tiny = {**both, "diffraction": np.full((1, 3), 0.3 * TRADE_SHARE / 2)}
    assert trades(m, unc, tiny) == []
    assert trades(m, Uncertainty({n: 0.01 for n in names}, names, np.eye(len(names)), "test"), both) == []


def test_albedo_on_the_engine_is_the_reference():
    """The assessment's albedo of every fit in one predict launch matches the float64 reference."""
    try:
        engine = Engine("diffuse+diffraction:hp:none+gtr:smith:dielectric")
    except Exception as e:          # noqa: BLE001 - no device builds here
        pytest.skip(f"no OpenCL device: {e}")
    m = engine.model
    rng = np.random.default_rng(3)
    x = m.search_x_lo + rng.random((5, m.n_free)) * (m.search_x_hi - m.search_x_lo)
    v = np.stack([m.from_x(r) for r in x])
    ref = directional_albedo(m, v)
    assert np.max(np.abs(directional_albedo(m, v, engine=engine) / ref - 1)) < 1e-5


def test_meat_on_the_engine_is_the_reference():
    """The sandwich's middle term summed by the kernel over every cell of a table cell set (some
    cells missing in one channel) matches the float64 reference summed over the same cells."""
    try:
        engine = Engine("diffuse+diffraction+ggx:smith:schlick")
    except Exception as e:          # noqa: BLE001 - no device builds here
        pytest.skip(f"no OpenCL device: {e}")
    from brdfcl.optim.uncertainty import meat
    m = engine.model
    assert engine.has_meat
    idx = select_cells(80.0, stride=97, offset=3)
    rng = np.random.default_rng(4)
    x = m.search_x_lo + rng.random((3, m.n_free)) * (m.search_x_hi - m.search_x_lo)
    v = np.stack([m.from_x(r) for r in x])
    data = np.stack([_noisy_table(m, v[k], idx, 0.1, seed=k) for k in range(2)]).astype(np.float32)
    data[1, 2, ::5] = np.nan
    cs = engine.upload(["a", "b"], idx, data)
    rows = np.array([0, 1, 1])
    got = engine.meat(cs, v, rows)
    want = meat(m, idx, data, v, rows=rows, cs=cs)
    assert np.all(np.isfinite(got))
    scale = np.sqrt(np.einsum("nii->ni", want))           # each entry on its correlation's scale
    err = np.abs(got - want) / (scale[:, :, None] * scale[:, None, :])
    assert err.max() < 1e-5, err.max()                    # measured 2e-7 (float32 PoCL)
