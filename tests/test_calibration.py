"""The calibration of the diffraction tests: synthetic cases, the NBRDF round trip, the
power and threshold arithmetic, and the verdict rule with its margins.  A few tiny cases only."""
import importlib.util
import os
from dataclasses import replace

import numpy as np
import pytest

from brdfcl.analysis import calibration as cal
from brdfcl.analysis import nbrdf, power
from brdfcl.analysis.analyze import RULE, Rule
from brdfcl.analysis.gradient import gradient_test
from brdfcl.analysis.wavelength import wavelength_check
from brdfcl.data.geometry import table_geometry
from brdfcl.model.synth import tabulate
from tests.conftest import SHARED

HALO = {"diffuse.rho": (0.003, 0.003, 0.003), "ct.rho": (0.5, 0.45, 0.4), "ct.F0": (0.8, 0.7, 0.6),
        "ct.alpha": 0.02, "diffraction.a": 0.5, "diffraction.rho": (1.0, 1.0, 1.0)}
HALO_SPEC = "diffuse+diffraction:hp:none+ggx:smith:schlick"
QUIET = cal.Effects(noise=0.02, grazing=0.2, missing=0.01)


def _case(share, spec=HALO_SPEC, params=HALO, cls="halo-hp"):
    return cal.Case(f"t-{share}", cls, share, spec, dict(params), QUIET, seed=7)


def _measured(case):
    """The measured table on the phi_d ~ 90 deg slice only (what the data tests read)."""
    return cal.synthesize(case, cal.slice_index())[1]


def test_case_share_is_the_share_asked_for():
    for s in (0.05, 0.9):
        model, v = cal.case_values(_case(s))
        assert cal.measured_share(model, v) == pytest.approx(s, abs=1e-9)


def test_measurement_effects():
    clean, _ = cal.synthesize(_case(0.5), np.arange(0, nbrdf.N_CELLS, 7))
    m = cal.measure(clean, cal.Effects(noise=0.03, grazing=0.3, missing=0.02), seed=1)
    there = np.isfinite(clean).all(axis=0)
    ok = np.isfinite(m).all(axis=0) & there
    assert 0.02 < 1 - ok.sum() / there.sum() < 0.2             # random cells and beyond 86 deg
    r = np.log(m[:, ok] / clean[:, ok])
    assert 0.02 < np.median(np.abs(r)) / 0.6745 < 0.06          # noise of ~3%, more at grazing
    assert abs(np.mean(r)) < 0.01


def test_strong_halo_is_detected_and_a_plastic_is_not():
    """The data tests on measured tables: a strong hp halo passes both, a plastic passes neither."""
    halo = _measured(_case(0.9))
    g = gradient_test(halo)
    assert g.n_cells.sum() > 300 and g.mean_score > 0.8
    assert wavelength_check(halo, [0.003 / np.pi] * 3).ratio < 1.0
    plastic = cal.Case("p", "plastic", 0.0, "diffuse+ggx:smith:dielectric",
                       {"diffuse.rho": (0.3, 0.1, 0.05), "ct.rho": (0.9, 0.9, 0.9), "ct.alpha": 0.05,
                        "ct.eta": 1.5}, QUIET, seed=3)
    t = _measured(plastic)
    g = gradient_test(t)
    assert g.mean_score < 0.2 or g.n_cells.sum() < 30
    assert wavelength_check(t, [0.3 / np.pi, 0.1 / np.pi, 0.05 / np.pi]).ratio > 1.5


def test_gradient_power_grows_with_the_share():
    """On one material, more diffraction never lowers the gradient score much, and the detection
    at the calibrated threshold, once reached, stays."""
    scores = [gradient_test(_measured(_case(s))).mean_score for s in (0.02, 0.1, 0.3, 0.6, 0.9)]
    assert scores[-1] > 0.8 and scores[0] < 0.3
    assert all(b > a - 0.05 for a, b in zip(scores, scores[1:])), scores
    hit = [s >= RULE.gradient_score for s in scores]
    assert hit == sorted(hit), (scores, RULE.gradient_score)


def test_plan_draws_every_class_with_the_peak_left_to_ct():
    plan = cal.Plan(shares=(0.5,), reps={"halo-hp": 1, "halo-abc": 1, "halo-gauss": 1},
                    nulls={k: 1 for k in cal.NULL_CLASSES}, roundtrip_every=2)
    cases = plan.cases()
    assert {c.cls for c in cases} == set(cal.POWER_CLASSES + cal.NULL_CLASSES)
    assert all(c.has_diffraction == (c.cls in cal.POWER_CLASSES) for c in cases)
    assert [c.name for c in plan.cases()] == [c.name for c in cases]           # deterministic
    assert len(plan.roundtrip(cases)) == len(cases)                            # one per class and share


# --- NBRDF --------------------------------------------------------------------------------------
def test_nbrdf_gradient_is_the_loss_derivative():
    rng = np.random.default_rng(1)
    P = nbrdf.init_weights(2, nbrdf.TrainOptions(), rng).astype(np.float64) * 10
    x, c = rng.normal(size=(40, 6)), rng.uniform(0, 1, 40)
    y, m = rng.uniform(0, 2, (2, 40, 3)), rng.random((2, 40)) > 0.2
    loss, cache = nbrdf._loss_terms(P, x, c, y, m)
    G = nbrdf._gradient(x, c, m, cache)
    h = 1e-6
    for j in range(0, nbrdf.N_WEIGHTS, 37):
        Q = P.copy()
        Q[:, j] += h
        up, _ = nbrdf._loss_terms(Q, x, c, y, m)
        Q[:, j] -= 2 * h
        dn, _ = nbrdf._loss_terms(Q, x, c, y, m)
        np.testing.assert_allclose(G[:, j], (up - dn) / (2 * h), atol=1e-8)


def test_nbrdf_interpolation_returns_table_entries_at_nodes():
    rng = np.random.default_rng(2)
    table = rng.uniform(0.01, 1.0, (3, nbrdf.N_CELLS))
    th, td, pd = nbrdf.node_angles()
    i, j, k = rng.integers(0, 89, 200), rng.integers(0, 89, 200), rng.integers(1, 179, 200)
    got = nbrdf.interpolate(nbrdf.stored_numbers(table), th[i], td[j], pd[k] + 1e-12)
    np.testing.assert_allclose(got, table[:, k + 180 * (j + 90 * i)], rtol=1e-6)


def test_nbrdf_training_lowers_the_loss_and_reproduces_a_simple_table():
    """A diffuse base under a broad GGX lobe, learnt in a few hundred steps (a raised learning rate)."""
    case = cal.Case("s", "rough-metal", 0.0, "diffuse+ggx:smith:none",
                    {"diffuse.rho": (0.4, 0.3, 0.2), "ct.rho": (0.3, 0.3, 0.3), "ct.alpha": 0.5}, QUIET, 0)
    model, v = cal.case_values(case)
    x, idx = nbrdf.node_inputs()
    sel = np.arange(0, idx.size, 101)
    sel = sel[table_geometry().mask(60.0)[idx[sel]]]
    table = tabulate(model, v)
    tr = nbrdf.train([table], nbrdf.TrainOptions(epochs=5, n_samples=20_000, learning_rate=1e-2))
    assert tr.loss[0, -1] < 0.5 * tr.loss[0, 0]
    assert tr.test_loss[0] < 0.03
    back = nbrdf.evaluate(tr.weights[0], x[sel]).T
    assert np.median(np.abs(back / table[:, idx[sel]] - 1)) < 0.1


def _merl_proxy_tool():
    path = SHARED / "tools" / "merl_proxy.py"
    if not path.exists():
        pytest.skip(f"{path} not available (set BRDFCL_SHARED)")
    spec = importlib.util.spec_from_file_location("merl_proxy", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_nbrdf_network_and_geometry_are_merl_proxy_s():
    tool = _merl_proxy_tool()
    weights = SHARED / "data" / "nbrdf" / "merl" / "aluminium.npz"
    if not weights.exists():
        pytest.skip(f"{weights} not available")
    w = tool.load_weights(str(weights))
    x_tool, cos_i, cos_o = tool.merl_geometry("node")
    valid = (cos_i > tool.HORIZON_EPS) & (cos_o > tool.HORIZON_EPS)
    x, idx = nbrdf.node_inputs()
    np.testing.assert_array_equal(idx, np.flatnonzero(valid))
    sel = idx[:: 997]
    np.testing.assert_allclose(x[:: 997], x_tool[sel], atol=1e-15)
    np.testing.assert_allclose(nbrdf.evaluate(w, x_tool[sel]), tool.nbrdf_eval(w, x_tool[sel]), rtol=1e-12)


# --- power and thresholds -----------------------------------------------------------------------
def _row(share, table="original", score=0.5, cells=100, ratio=1.0, gain=0.1, cls="x"):
    return {"share": share, "table": table, "grad_score": score, "grad_cells": cells, "wl_ratio": ratio,
            "law_ratio": ratio,
            "lobe_gain": gain, "class": cls, "case": f"{cls}{share}{score}{gain}"}


def test_threshold_keeps_false_positives_at_the_target():
    rng = np.random.default_rng(3)
    nulls = [_row(0.0, score=s) for s in rng.uniform(0, 0.6, 100)]
    for fp in (0.0, 0.05, 0.2):
        t = power.threshold_at(nulls, "gradient", fp)
        k, n = power.rate(nulls, "gradient", t)
        assert k <= fp * n
        assert power.rate(nulls, "gradient", t - 0.02)[0] > k or fp == 0 or k == 0
    undecided = [_row(0.0, score=0.9, cells=5)]                 # too few cells: detects nothing
    assert not power.detects(undecided[0], "gradient", 0.1)


def test_smallest_share_interpolates_the_crossing():
    curve = [(0.1, 0, 10), (0.2, 5, 10), (0.4, 10, 10), (0.8, 10, 10)]
    s = power.smallest_share(curve, 0.9)
    assert 0.2 < s < 0.4
    assert power.smallest_share([(0.1, 10, 10), (0.5, 8, 10)]) != power.smallest_share([(0.1, 10, 10)])
    assert np.isnan(power.smallest_share([(0.1, 1, 10), (0.5, 2, 10)]))


def test_chosen_rule_respects_the_false_positive_target_on_each_class():
    rng = np.random.default_rng(4)
    rows = []
    for table in ("original", "roundtrip"):
        rows += [_row(0.0, table, score=s, gain=g, ratio=r, cls=("a", "b")[i % 2]) for i, (s, g, r) in
                 enumerate(zip(rng.uniform(0, 0.5, 40), rng.normal(-0.05, 0.03, 40), rng.uniform(0.95, 1.5, 40)))]
        rows += [_row(sh, table, score=min(1, sh + rng.uniform(0, 0.4)), gain=sh - 0.1, ratio=rng.uniform(0.5, 1.1))
                 for sh in (0.1, 0.3, 0.6, 0.9) for _ in range(5)]
    rule, mean_power = power.choose_rule(rows, fp=0.05)
    for table in ("original", "roundtrip"):
        for cls in ("a", "b"):
            k, n = power.rate([r for r in rows if r["share"] == 0 and r["table"] == table and r["class"] == cls],
                              "verdict", rule=rule)
            assert k <= 0.05 * n
    assert mean_power > 0.3
    hits = [power.detects(r, "verdict", rule=rule) for r in rows if r["share"] > 0]
    assert np.mean(hits) == pytest.approx(mean_power)     # the vectorised choice counts as detects does


def test_rule_margins_and_verdicts():
    rule = Rule(gradient_score=0.1, gradient_decisive=0.5, min_cells=30, wavelength_decisive=0.98,
                wavelength_veto=1.5, lobe_gain=0.0, gradient_required=False)
    m = rule.margins(0.7, 100, 1.0, 0.2)
    assert m["gradient"] == pytest.approx(0.6) and m["lobe"] == pytest.approx(0.2)
    assert m["wavelength"] == pytest.approx(np.log(1.5))
    assert m["evidence"] == pytest.approx(0.2)                                     # the gradient's
    assert rule.verdict(m) == "diffraction" and rule.binding(m) == "evidence"
    assert rule.verdict(rule.margins(0.3, 100, 1.0, 0.2)) == "none"               # no evidence
    assert rule.binding(rule.margins(0.3, 100, 1.0, 0.2)) == "evidence"
    assert rule.verdict(rule.margins(0.3, 100, 0.9, 0.2)) == "diffraction"        # the law is evidence
    assert rule.verdict(rule.margins(0.05, 100, 0.9, 0.2)) == "none"              # gradient contradicts
    assert rule.verdict(rule.margins(0.05, 10, 0.9, 0.2)) == "diffraction"        # ... but cannot decide
    assert rule.verdict(rule.margins(0.9, 100, 1.5, 0.2)) == "none"               # the law vetoes
    assert rule.verdict(rule.margins(0.9, 100, float("nan"), 0.2)) == "diffraction"
    assert rule.verdict(rule.margins(0.05, 10, float("nan"), 0.2)) == "none"      # nothing decides
    assert rule.binding(rule.margins(0.05, 100, 2.0, -0.1)) == "gradient+wavelength+lobe+evidence"
    strict = replace(rule, gradient_required=True)
    assert strict.verdict(strict.margins(0.3, 10, 0.9, 0.2)) == "none"            # must decide
    assert strict.binding(strict.margins(0.3, 10, 0.9, 0.2)) == "gradient"
    arrays = rule.margins(np.array([0.7, 0.3, 0.05]), np.array([100, 100, 10]), np.array([1.0, 1.0, 0.9]), 0.2)
    assert list(rule.diffraction(arrays)) == [True, False, True]                 # arrays as numbers


def test_each_wavelength_test_reads_its_ratio():
    """law, colour, the larger of the two (the law's alone where the colour is unknown), collapse."""
    ratio = {t: Rule(wavelength_test=t).wavelength_ratio for t in ("law", "colour", "both", "collapse")}
    assert [ratio[t](0.9, 2.0, 1.01) for t in ("law", "colour", "both", "collapse")] == [0.9, 1.01, 1.01, 2.0]
    assert ratio["both"](1.2, 2.0, 0.5) == 1.2 and ratio["both"](0.9, 2.0, float("nan")) == 0.9
    assert list(ratio["both"](np.array([0.9, 1.1]), 2.0, np.array([1.0, np.nan]))) == [1.0, 1.1]
    both = Rule(wavelength_test="both", wavelength_decisive=0.99)
    law = Rule(wavelength_test="law", wavelength_decisive=0.99)
    # a law ratio below 1 that the colour does not share: evidence for the law, not for both
    for rule, verdict in ((law, "diffraction"), (both, "none")):
        assert rule.verdict(rule.margins(0.35, 200, rule.wavelength_ratio(0.88, 1.0, 1.008), 0.1)) == verdict


@pytest.mark.skipif(os.environ.get("BRDFCL_FAST") == "1", reason="fits")
def test_lobe_comparison_keeps_a_strong_halo_and_drops_it_for_a_metal():
    """Fits of the compared variants on two tiny-budget cases: the halo keeps its lobe, a GGX metal
    without diffraction does not, and the verdicts follow."""
    from brdfcl.optim.fit import FitOptions
    metal = cal.Case("m", "metal-ggx", 0.0, "diffuse+ggx:smith:schlick",
                     {k: v for k, v in HALO.items() if not k.startswith("diffraction")}, QUIET, seed=5)
    cases = [_case(0.9), metal]
    tables = {c.name: cal.synthesize(c)[1] for c in cases}
    compared = cal.Compared(FitOptions(n_candidates=64, n_starts=2, local_maxeval=60))
    rows = {r["case"]: r for r in cal.analyse_cases(cases, tables, compared)}
    assert rows["t-0.9"]["lobe_gain"] > 0.1 and rows["t-0.9"]["verdict"] == "diffraction"
    assert rows["m"]["lobe_gain"] < 0 and rows["m"]["verdict"] == "none"
    assert rows["t-0.9"]["margin_lobe"] > 0 > rows["m"]["margin_lobe"]


def test_calibrate_command_and_summary(tmp_path):
    """The command's parser, and the summary (table and figures) from rows alone."""
    import argparse

    from brdfcl.app import calibrate
    ap = argparse.ArgumentParser()
    calibrate.add_parser(ap.add_subparsers(dest="cmd"))
    args = ap.parse_args(["calibrate", "--out", str(tmp_path), "--quick"])
    assert args.func is calibrate.run and args.quick and args.fp == calibrate.FP_TARGET
    rng = np.random.default_rng(5)
    rows = []
    for table in ("original", "roundtrip"):
        for cls in ("metal-ggx", "plastic"):
            rows += [_row(0.0, table, score=s, gain=-0.06, ratio=5.0, cls=cls) for s in rng.uniform(0, 0.3, 10)]
        rows += [_row(sh, table, score=min(1.0, 1.2 * sh), gain=sh - 0.1, ratio=0.8, cls="halo-hp")
                 for sh in (0.1, 0.5, 0.9) for _ in range(3)]
    for r in rows:
        r.update(noise=0.02, missing=0.01, rmse_full=0.01, rmse_no_diffraction=0.01, nbrdf_test_loss="")
    res = calibrate.summarise(tmp_path, rows, epochs=2, log=None)
    text = (tmp_path / "calibration.md").read_text()
    assert "Smallest diffraction share" in text and "| verdict:calibrated |" in text
    assert all((tmp_path / f).stat().st_size > 20000 for f in ("power.png", "statistics.png", "verdict.png"))
    assert res["smallest"]["gradient", "original"] <= 0.5
    k, n = res["fp"]["verdict:calibrated", "roundtrip"]
    assert k <= 0.05 * n
