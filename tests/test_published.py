"""bench/published.py and bench/published/*.csv: the published fits of the MERL materials (SGD, Bagher et al. 2012;
ABC, Ashikhmin-Shirley and Cook-Torrance, Low et al. 2012; seven models of Ngan et al. 2005), and their evaluation
(no OpenCL)."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, special

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("bench_published", ROOT / "bench" / "published.py")
published = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(published)

BBM_COMMIT = "9807fb38d7ab51802f3a0fe0f65cf763cb01a0f4"
RGB = ("r", "g", "b")
_KDKS = ["kd_r", "kd_g", "kd_b", "ks_r", "ks_g", "ks_b"]
COLUMNS = {
    "sgd_bagher2012": [f"{p}_{c}" for p in ("rho_d", "rho_s", "alpha", "p", "F0", "F1", "K_ap", "Lambda", "c", "k",
                                            "theta0") for c in RGB],
    "abc_low2012_microfacet_e2": ["kd_r", "kd_g", "kd_b", "A_r", "A_g", "A_b", "B", "C", "eta"],
    "abc_low2012_smooth_e2": ["kd_r", "kd_g", "kd_b", "A_r", "A_g", "A_b", "B", "C", "eta"],
    "ashikhminshirley_low2012_e1": _KDKS + ["n", "eta"],
    "ashikhminshirley_low2012_e2": _KDKS + ["n", "eta"],
    "cooktorrance_low2012_e1": _KDKS + ["m", "eta"],
    "cooktorrance_low2012_e2": _KDKS + ["m", "eta"],
    "ashikhminshirley_ngan2005": _KDKS + ["F0", "n"],
    "blinnphong_ngan2005": _KDKS + ["n"],
    "cooktorrance_ngan2005": _KDKS + ["F0", "m"],
    "he_ngan2005": _KDKS + ["tau", "sigma", "eta"],
    "lafortune_ngan2005": _KDKS + ["Cxy", "Cz", "n"],
    "ward_ngan2005": _KDKS + ["alpha"],
    "wardduer_ngan2005": _KDKS + ["alpha"],
}
NGAN = sorted(m for m in COLUMNS if m.endswith("_ngan2005"))
# The MERL materials missing from Ngan et al.'s fits (86 of MERL's 100).
NOT_IN_NGAN = {"color-changing-paint1", "color-changing-paint2", "color-changing-paint3", "dark-specular-fabric",
               "grease-covered-steel", "light-brown-fabric", "pink-fabric2", "red-fabric2", "silver-metallic-paint2",
               "two-layer-gold", "two-layer-silver", "white-fabric", "white-fabric2", "white-marble"}
# Some of MERL's 100 names, spelled as MERL spells them.
SOME_MERL = ("alum-bronze", "gold-metallic-paint3", "silicon-nitrade", "white-diffuse-bball", "two-layer-silver",
             "specular-violet-phenolic", "ss440", "aventurnine", "yellow-plastic", "blue-metallic-paint2")


def _hemisphere(rng, n):
    z = rng.random(n)
    r = np.sqrt(1.0 - z * z)
    phi = 2.0 * np.pi * rng.random(n)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _direction(theta_deg, phi_deg):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def test_models_and_files():
    assert set(published.MODELS) == set(COLUMNS)
    merl = set(published.load("sgd_bagher2012"))
    assert len(merl) == 100 and all(m in merl for m in SOME_MERL)
    for model in published.MODELS:
        path = published.DATA_DIR / f"{model}.csv"
        header = [line for line in path.read_text().splitlines() if line.startswith("#")]
        assert any(BBM_COMMIT in line and "fits/" in line for line in header), model
        assert any("1.15/1500" in line for line in header), model       # the scale is stated
        fits = published.load(model)
        # Low et al. and Bagher et al. fitted all 100 MERL materials, Ngan et al. 86 of them, MERL's names
        assert set(fits) == (merl - NOT_IN_NGAN if model in NGAN else merl), model
        for params in fits.values():
            assert list(params) == COLUMNS[model]
            assert all(np.isfinite(v) for v in params.values())
    assert set(published.RGB_SCALE) == set(NGAN)


def test_ngan_scale():
    """Ngan et al.'s numbers are on MERL / 1500 in every channel: their Lambertian albedos are 1/1.15 and 1/1.66 of
    the SGD fits' in G and B (median over the materials, to ~0.1), which RGB_SCALE undoes."""
    sgd = published.load("sgd_bagher2012")
    for model in NGAN:
        fits = published.load(model)
        ratio = np.array([[fits[m][f"kd_{c}"] / sgd[m][f"rho_d_{c}"] for c in RGB] for m in fits
                          if min(sgd[m][f"rho_d_{c}"] for c in RGB) > 1e-3])
        med = np.median(ratio, axis=0) * np.array(published.RGB_SCALE[model])
        np.testing.assert_allclose(med / med[0], 1.0, atol=0.12, err_msg=model)
    for model in set(COLUMNS) - set(NGAN) - {"sgd_bagher2012"}:
        if "kd_r" in COLUMNS[model]:
            fits = published.load(model)
            med = np.median([[fits[m][f"kd_{c}"] / sgd[m][f"rho_d_{c}"] for c in RGB] for m in fits
                             if min(sgd[m][f"rho_d_{c}"] for c in RGB) > 1e-3], axis=0)
            np.testing.assert_allclose(med / med[0], 1.0, atol=0.12, err_msg=model)


def test_numbers_are_the_published_ones():
    # A few values copied by hand from BBM's fits/*.fit (commit above).
    sgd = published.load("sgd_bagher2012")
    assert sgd["alum-bronze"]["rho_d_r"] == 0.0478786
    assert sgd["alum-bronze"]["F0_r"] == 6.05524 and sgd["alum-bronze"]["F1_r"] == 5.05524
    assert sgd["black-obsidian"]["c_g"] == 9.46657e+50
    assert sgd["chrome"]["theta0_b"] == 1.00293
    abc = published.load("abc_low2012_microfacet_e2")
    assert abc["alum-bronze"]["A_b"] == 27.37309 and abc["alum-bronze"]["B"] == 10482.133785
    assert abc["chrome-steel"]["eta"] == 99.99961
    smooth = published.load("abc_low2012_smooth_e2")
    assert smooth["alum-bronze"]["C"] == 0.663506 and smooth["aluminium"]["kd_b"] == 0.0033
    ct = published.load("cooktorrance_low2012_e1")["chrome-steel"]
    assert ct["ks_r"] == 0.02447 and ct["m"] == 0.005483 and ct["eta"] == 9.37431
    laf = published.load("lafortune_ngan2005")["chrome-steel"]
    assert laf["kd_g"] == 0.0236 and laf["Cxy"] == -0.577 and laf["Cz"] == 0.577 and laf["n"] == 9160.0
    he = published.load("he_ngan2005")["blue-acrylic"]
    assert he["ks_r"] == 2.93 and he["tau"] == 28.7 and he["sigma"] == 0.063 and he["eta"] == 1.08
    ward = published.load("ward_ngan2005")["blue-acrylic"]
    assert ward["kd_b"] == 0.0636 and ward["ks_r"] == 0.00774 and ward["alpha"] == 0.0162
    # load() hands out copies
    sgd["alum-bronze"]["rho_d_r"] = -1.0
    assert published.load("sgd_bagher2012")["alum-bronze"]["rho_d_r"] == 0.0478786


def _upper_gamma(s, x):
    """Gamma(s, x) for any real s (recursion Gamma(s, x) = (Gamma(s + 1, x) - x^s e^-x) / s for s <= 0)."""
    if s > 0:
        return special.gammaincc(s, x) * special.gamma(s)
    return (_upper_gamma(s + 1.0, x) - x**s * np.exp(-x)) / s


def test_sgd_normalisation_matches_the_published_K():
    """K_ap = 1 / (alpha Gamma(1 - p, alpha)) for every material and channel: D as evaluated integrates to 1
    over the projected hemisphere with the published K, which pins D's form."""
    for material, p in published.load("sgd_bagher2012").items():
        for c in RGB:
            a, power = p[f"alpha_{c}"], p[f"p_{c}"]
            assert p[f"K_ap_{c}"] * a * _upper_gamma(1.0 - power, a) == pytest.approx(1.0, rel=2e-5), (material, c)


def test_sgd_distribution_is_normalised_numerically():
    """int D(h) cos(theta_h) dw_h = 1 with D read back from evaluate(): at wi = wo = h (theta_d = 0)
    f - rho_d / pi = rho_s D G1(h)^2 (F0 - F1) / (pi cos^2 theta_h)."""
    p = published.load("sgd_bagher2012")["gold-metallic-paint3"]
    theta = np.linspace(0.0, np.radians(89.0), 20001)
    h = np.stack([np.sin(theta), 0 * theta, np.cos(theta)], axis=1)
    f = published.evaluate("sgd_bagher2012", "gold-metallic-paint3", h, h)
    for i, c in enumerate(RGB):
        spec = f[i] - p[f"rho_d_{c}"] / np.pi
        g1 = np.where(theta > p[f"theta0_{c}"], 1 + p[f"Lambda_{c}"] * (
            1 - np.exp(p[f"c_{c}"] * np.maximum(theta - p[f"theta0_{c}"], 0) ** p[f"k_{c}"])), 1.0)
        fresnel = p[f"F0_{c}"] - p[f"F1_{c}"]
        d = spec * np.pi * np.cos(theta) ** 2 / (p[f"rho_s_{c}"] * g1**2 * fresnel)
        integral = integrate.trapezoid(d * np.cos(theta) * np.sin(theta), theta) * 2 * np.pi
        assert integral == pytest.approx(1.0, abs=1e-3), c


@pytest.mark.parametrize("model", sorted(COLUMNS))
def test_finite_non_negative_reciprocal(model):
    rng = np.random.default_rng(7)
    wi, wo = _hemisphere(rng, 300), _hemisphere(rng, 300)
    wo[:100] = wi[:100] * np.array([-1.0, -1.0, 1.0])           # exact mirror pairs: the specular peak
    wo[100:110] = wi[100:110]                                   # retro-reflection
    for material in published.load(model):
        f = published.evaluate(model, material, wi, wo)
        assert f.shape == (3, 300) and f.dtype == np.float64
        assert np.all(np.isfinite(f)), material
        # an empirical property of these published numbers at these directions (the SGD form does not
        # guarantee it; see evaluate()'s docstring)
        assert np.all(f >= 0), material
        np.testing.assert_allclose(published.evaluate(model, material, wo, wi), f, rtol=1e-12, atol=0,
                                   err_msg=material)


@pytest.mark.parametrize("model", sorted(COLUMNS))
def test_below_horizon_and_errors(model):
    wi = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, -0.8], [0.6, 0.0, 0.8]])
    wo = np.array([[0.0, 0.6, -0.8], [0.0, 0.0, 1.0], [-0.6, 0.0, 0.8]])
    f = published.evaluate(model, "alum-bronze", wi, wo)
    assert np.all(f[:, :2] == 0) and np.all(f[:, 2] > 0)
    with pytest.raises(KeyError):
        published.evaluate(model, "no-such-material", wi, wo)
    with pytest.raises(ValueError):
        published.evaluate(model, "alum-bronze", wi[:, :2], wo[:, :2])
    with pytest.raises(KeyError):
        published.load("no-such-model")


# Reference values from BBM's own implementation: BBM commit 9807fb38d7ab51802f3a0fe0f65cf763cb01a0f4, native
# backbone, configuration doubleRGB, bsdf_import<doubleRGB>(line of fits/bagher_sgd.fit, fits/low_lowmicrofacet_E2.fit
# or fits/low_lowsmooth_E2.fit).eval(in, out) (Aggregate of Lambertian and Bagher / LowMicrofacetFit / LowSmooth),
# compiled with g++ 12.2 -std=c++20, at in = _direction(*PAIRS[i][0]), out = _direction(*PAIRS[i][1])
# (theta, phi in degrees), printed with 17 digits.
PAIRS = [((0, 0), (0, 0)), ((30, 0), (31, 181)), ((60, 45), (40, 200)), ((80, 10), (75, 170))]
BBM_REFERENCE = {
    ("sgd_bagher2012", "alum-bronze"): [
        (1.1832609844567736, 0.42227321042927296, 0.20470556037390458),
        (2.2430320579526057, 0.7899054991772805, 0.4315786623779768),
        (0.016160546850653965, 0.02421515555637292, 0.03768951151796643),
        (0.015240231716639248, 0.009979470568229464, 0.006397254052215144),
    ],
    ("sgd_bagher2012", "gold-metallic-paint3"): [
        (89.55761208945097, 73.46910731482569, 48.49857948932058),
        (12.387749253215627, 10.075361309666093, 4.7768932651575415),
        (0.01843689057962858, 0.01326234957685902, 0.008632818761213351),
        (0.01843689057962858, 0.01326234957685902, 0.008632818761213351),
    ],
    ("sgd_bagher2012", "blue-fabric"): [
        (0.007709077174998191, 0.008526734612434292, 0.019265968183162712),
        (0.008843677446784975, 0.009840353565262071, 0.02177462732772424),
        (0.012444288894178385, 0.013868302245825963, 0.028426172740903116),
        (0.03870853804307782, 0.04122972751908544, 0.040244226508417726),
    ],
    ("abc_low2012_microfacet_e2", "alum-bronze"): [
        (2.4105485459724423, 1.7695185412002121, 1.2769590574159824),
        (2.3137056446339863, 1.698484146524589, 1.2256990260669969),
        (0.05309447590864493, 0.04032290034153093, 0.029132238257299867),
        (0.21340667201742233, 0.15791210566601813, 0.1139872775486253),
    ],
    ("abc_low2012_microfacet_e2", "gold-metallic-paint3"): [
        (80.87324292267829, 60.67987117852447, 34.02865131494247),
        (19.613476541816443, 14.716155639490205, 8.25266961228927),
        (0.06346201873715195, 0.04761608391765919, 0.026702612994183767),
        (0.12582264368866813, 0.09440578285786543, 0.052941797742666094),
    ],
    ("abc_low2012_microfacet_e2", "blue-fabric"): [
        (0.019013292693466834, 0.021177090327264513, 0.03981024438349995),
        (0.013658780912753084, 0.015258430837620511, 0.03032367673181367),
        (0.011447697271347434, 0.012814388931925474, 0.02640630846244448),
        (0.09651606405777999, 0.1068455008182684, 0.1771216023282061),
    ],
    ("abc_low2012_smooth_e2", "alum-bronze"): [
        (7.876702637554628, 5.793751974784174, 4.159272547994349),
        (2.4647554929223494, 1.8138918462661473, 1.302258405258816),
        (0.05874072910831456, 0.04454673419746294, 0.03210220747239852),
        (0.2651922598052868, 0.19636791676524337, 0.14108977280286628),
    ],
    ("abc_low2012_smooth_e2", "gold-metallic-paint3"): [
        (158.46683601866476, 119.0557532739579, 66.99121264889368),
        (19.379328000734596, 14.559642579087084, 8.192532366437602),
        (0.060983974903776696, 0.04581711386573095, 0.02578072821793772),
        (0.10867999053806733, 0.08165101584909683, 0.045944025511797854),
    ],
    ("abc_low2012_smooth_e2", "blue-fabric"): [
        (0.009064799671788134, 0.010240899662624411, 0.021514241786643636),
        (0.009345008240462242, 0.010572543152487936, 0.0220412206497489),
        (0.01073086036845827, 0.012212781487590165, 0.024647546296031143),
        (0.08520790405641575, 0.10036078781112003, 0.16471402604657684),
    ],
}


@pytest.mark.parametrize("key", sorted(BBM_REFERENCE))
def test_agrees_with_bbm(key):
    model, material = key
    wi = np.array([_direction(*a) for a, _ in PAIRS])
    wo = np.array([_direction(*b) for _, b in PAIRS])
    expected = np.array(BBM_REFERENCE[key]).T
    np.testing.assert_allclose(published.evaluate(model, material, wi, wo), expected, rtol=1e-8, atol=0)


# Reference values of BBM's own implementation for the Low et al. Ashikhmin-Shirley / Cook-Torrance and the Ngan et
# al. fits, printed by bench/published_bbm_check.cpp (each file's header: BBM commit, configuration) at the pairs of
# tests/data/published_bbm/directions.txt (a third of them near the mirror direction), on BBM's scale (Ngan's
# without RGB_SCALE).  Against 300 pairs and every material the differences are below 1e-13 (published.py).
BBM_DATA = ROOT / "tests" / "data" / "published_bbm"


def _bbm_table(model):
    rows = [line.split() for line in (BBM_DATA / f"{model}.txt").read_text().splitlines() if not line.startswith("#")]
    out = {}
    for material, i, *rgb in rows:
        out.setdefault(material, {})[int(i)] = [float(v) for v in rgb]
    return out


@pytest.mark.parametrize("model", sorted(set(COLUMNS) - {"sgd_bagher2012", "abc_low2012_microfacet_e2",
                                                          "abc_low2012_smooth_e2"}))
def test_agrees_with_bbm_table(model):
    pairs = np.loadtxt(BBM_DATA / "directions.txt", comments="#")
    table = _bbm_table(model)
    assert len(table) == 3
    scale = np.array(published.RGB_SCALE.get(model, (1.0, 1.0, 1.0)))[:, None]
    for material, values in table.items():
        assert sorted(values) == list(range(len(pairs)))
        expected = np.array([values[i] for i in range(len(pairs))]).T
        assert np.all(np.isfinite(expected)) and np.all(expected > 0)
        f = published.evaluate(model, material, pairs[:, :3], pairs[:, 3:]) / scale
        np.testing.assert_allclose(f, expected, rtol=1e-12, atol=0, err_msg=material)


def test_he_table_covers_the_rough_approximation():
    """He et al.'s D is BBM's Taylor sum where g (the smallest over the channels) is at most 18, its rough
    approximation from g = 19 on and a linear blend between: the BBM table has chrome-steel pairs in all three."""
    p = published.load("he_ngan2005")["chrome-steel"]
    pairs = np.loadtxt(BBM_DATA / "directions.txt", comments="#")
    wi, wo = pairs[:, :3], pairs[:, 3:]
    g = ((2 * np.pi * published._he_sigma(p["tau"], p["sigma"], wi, wo) * (wi[:, 2] + wo[:, 2])
          / published.HE_WAVELENGTH) ** 2).min(axis=0)
    assert np.sum(g <= 18) >= 10 and np.sum((g > 18) & (g < 19)) >= 4 and np.sum(g >= 19) >= 4
