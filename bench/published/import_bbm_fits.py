"""Write bench/published/<model>.csv for the Low et al. 2012 (Ashikhmin-Shirley, Cook-Torrance) and Ngan et al.
2005 fits from BBM's fits/*.fit, numbers copied verbatim (the same digits, not re-printed floats).

Run once, offline, against a local copy of BBM (github.com/bsdfbenchmark/bbm):

    python bench/published/import_bbm_fits.py /work/.mirror/bsdfbenchmark+bbm/repo

The argument is a git directory of BBM (bare or not; read with ``git show HEAD:fits/<name>.fit``, the commit
from ``git rev-parse HEAD`` goes into each header) or a folder holding the ``.fit`` files (then pass the commit
with ``--commit``).  The SGD and ABC files (sgd_bagher2012, abc_low2012_*) were made by hand and are not
rewritten.  Each header states the source, the scale and every column; bench/published.py evaluates the fits.
"""
from __future__ import annotations

import argparse
import re
import subprocess
from pathlib import Path

OUT = Path(__file__).resolve().parent

_LOW = ('J. Low (Löw), J. Kronander, A. Ynnerman, J. Unger, "BRDF models for accurate and efficient rendering of '
        'glossy\n# surfaces", ACM Transactions on Graphics 31(1), 2012, https://doi.org/10.1145/2077341.2077350 '
        '(supplemental material)')
_NGAN = ('A. Ngan, F. Durand, W. Matusik, "Experimental analysis of BRDF models", Eurographics Symposium on '
         'Rendering\n# 2005, https://dl.acm.org/doi/10.5555/2383654.2383671 (the link BBM gives; the paper\'s '
         'supplemental fits)')

_SCALE_MERL = (
    "# Scale: BRDF values in 1/sr on MERL's scaled RGB, i.e. the stored MERL numbers times (1/1500, 1.15/1500, "
    "1.66/1500)\n# for (R, G, B), the scale brdfcl.data.merl applies and BBM's MERL reader (include/staticmodel/"
    "merl.h) applies; the\n# fits' Lambertian albedos agree with those of the SGD fits on that scale (median ratio "
    "1.02-1.09 per channel over\n# the 100 materials, in each of the four Low et al. Ashikhmin-Shirley and "
    "Cook-Torrance files), so bench/published.py makes no conversion.")
_SCALE_NGAN = (
    "# Scale: the numbers are BRDFs in 1/sr on MERL's stored numbers times 1/1500 in every channel, without the "
    "1.15 and 1.66\n# of G and B: on MERL's scaled RGB (the stored numbers times (1/1500, 1.15/1500, 1.66/1500) for "
    "(R, G, B), the scale\n# brdfcl.data.merl and BBM's MERL reader apply) the G and B values of every term are "
    "1.15 and 1.66 times these.\n# Evidence: the median ratio of these Lambertian albedos to the SGD fits' is "
    "1.00-1.10 in R, 0.85-0.97 in G and\n# 0.57-0.66 in B over the 86 materials, in each of the seven Ngan et al. "
    "files (1/1.15 = 0.87, 1/1.66 = 0.60); with\n# the factors the median model/proxy ratio on 8 MERL-proxy "
    "tables is the same in R, G and B within 0.04 for each\n# model (0.86-1.00).  BBM evaluates the numbers as "
    "they are; bench/published.py multiplies G by 1.15 and B by 1.66\n# (published.RGB_SCALE).")

_E = {
    "E1": "# E1: the fits minimise the paper's first error metric, a cosine-weighted squared error of the BRDF.",
    "E2": ("# E2: the fits minimise the paper's second error metric, the cosine-weighted log error\n"
           "#   sum (ln(1 + f cos theta_i) - ln(1 + f_ref cos theta_i))^2 (as BBM implements it in "
           "include/loss/cosine_weighted_log.h)."),
}
_KD = "#   kd_r, kd_g, kd_b   diffuse albedo (Lambertian term kd / pi), unitless, per channel"
_KS = "#   ks_r, ks_g, ks_b   specular scale (BBM's albedo of the specular term), per channel"

# model -> (BBM fit file stem, BBM class of the specular term, [(BBM attribute, csv column), ...] after the
# Lambertian albedo (kd) and the specular albedo (ks), paper, formula and column lines, notes)
SPECS: dict[str, dict] = {}


def _low_as(metric: str) -> dict:
    return dict(
        fit=f"low_ashikhminshirley_{metric}", cls="LowAshikhminShirley",
        attrs=[("sharpness", "n"), ("fresnelReflectance", "eta")], paper=_LOW, metric=metric, scale=_SCALE_MERL,
        what=f'("{metric}" metric) of the isotropic Ashikhmin-Shirley specular lobe (M. Ashikhmin, P. Shirley, "An '
             'anisotropic Phong\n# BRDF model", Journal of Graphics Tools 5(2), 2000) with a Lambertian term',
        form="Aggregate(Lambertian(albedo=kd), LowAshikhminShirley(albedo=ks, sharpness=n, fresnelReflectance=eta))",
        lines=["#   f(wi, wo) = kd / pi + ks * (n + 1) / (8 pi) * cos(theta_h)^n * F(wi.h) / (wi.h * max(cos theta_i, "
               "cos theta_o))", _KD, _KS,
               "#   n                  Phong exponent of cos(theta_h), unitless",
               "#   eta                index of refraction of the exact unpolarised dielectric Fresnel F "
               "(Cook-Torrance form), at wi.h;\n#                      BBM names it fresnelReflectance but, "
               "with Low et al.'s Cook-Torrance Fresnel, it is an index"],
        notes="# BBM: include/bsdfmodel/low.h (lowashikhminshirley), ashikhminshirley.h, bbm/fresnel_cook.h.")


def _low_ct(metric: str) -> dict:
    return dict(
        fit=f"low_cooktorrance_{metric}", cls="LowCookTorrance", attrs=[("roughness", "m"), ("eta", "eta")],
        paper=_LOW, metric=metric, scale=_SCALE_MERL,
        what=f'("{metric}" metric) of the Cook-Torrance specular lobe (R. L. Cook, K. E. Torrance, "A reflectance '
             'model for computer\n# graphics", ACM TOG 1(1), 1982) with a Lambertian term',
        form="Aggregate(Lambertian(albedo=kd), LowCookTorrance(albedo=ks, roughness=m, eta))",
        lines=["#   f(wi, wo) = kd / pi + ks * D(h) * G * F(cd) / (pi * cos(theta_i) * cos(theta_o))", _KD, _KS,
               "#   m                  Beckmann roughness: D(h) = exp(-tan^2(theta_h) / m^2) / (m^2 "
               "cos^4(theta_h)), without a 1/pi\n#                      (BBM's ndf::beckmann with Normalize = false), "
               "unitless",
               "#   eta                index of refraction of the exact unpolarised dielectric Fresnel F "
               "(Cook-Torrance form) at\n#                      cd = cos(theta_d), the mean of wi.h and wo.h",
               "#   G                  V-groove shadowing min(1, 2 cos(theta_h) cos(theta_i) / wi.h, 2 cos(theta_h) "
               "cos(theta_o) / wo.h)"],
        notes="# BBM: include/bsdfmodel/low.h (lowcooktorrance), cooktorrance.h, microfacet.h, ndf/beckmann.h,\n"
              "# maskingshadowing/vgroove.h, bbm/fresnel_cook.h.")


def _ngan(cls: str, fit: str, attrs: list, what: str, form: str, lines: list, notes: str) -> dict:
    return dict(fit=fit, cls=cls, attrs=attrs, paper=_NGAN, metric=None, scale=_SCALE_NGAN, what=what, form=form,
                lines=lines, notes=notes)


SPECS.update({
    "ashikhminshirley_low2012_e1": _low_as("E1"),
    "ashikhminshirley_low2012_e2": _low_as("E2"),
    "cooktorrance_low2012_e1": _low_ct("E1"),
    "cooktorrance_low2012_e2": _low_ct("E2"),
    "ashikhminshirley_ngan2005": _ngan(
        "NganAshikhminShirley", "ngan_ashikhminshirley", [("fresnelReflectance", "F0"), ("sharpness", "n")],
        'of the isotropic Ashikhmin-Shirley specular lobe (M. Ashikhmin, P. Shirley, "An anisotropic Phong BRDF '
        'model",\n# Journal of Graphics Tools 5(2), 2000) with a Lambertian term',
        "Aggregate(Lambertian(albedo=kd), NganAshikhminShirley(albedo=ks, fresnelReflectance=F0, sharpness=n))",
        ["#   f(wi, wo) = kd / pi + ks * (n + 1) / (8 pi) * cos(theta_h)^n * F(wi.h) / (wi.h * max(cos theta_i, "
         "cos theta_o))", _KD, _KS,
         "#   F0                 Schlick Fresnel F(c) = F0 + (1 - F0)(1 - c)^5, F0 the reflectance at normal "
         "incidence, unitless",
         "#   n                  Phong exponent of cos(theta_h), unitless"],
        "# BBM: include/bsdfmodel/ngan.h (nganashikhminshirley), ashikhminshirley.h, bbm/fresnel_schlick.h."),
    "blinnphong_ngan2005": _ngan(
        "NganBlinnPhong", "ngan_blinnphong", [("sharpness", "n")],
        "of the normalised (Blinn-)Phong specular lobe with a Lambertian term",
        "Aggregate(Lambertian(albedo=kd), NganBlinnPhong(albedo=ks, sharpness=n))",
        ["#   f(wi, wo) = kd / pi + ks * (n + 2) / (2 pi) * max(R(wi).wo, 0)^n,  R(wi) = (-x, -y, z) of wi (the "
         "mirror direction)", _KD, _KS, "#   n                  exponent, unitless"],
        "# BBM evaluates NganBlinnPhong as its modified Phong model (include/bsdfmodel/ngan.h: an alias of phong.h):\n"
        "# the cosine of the angle between the mirror direction and wo, not Blinn's cos(theta_h) of Ngan et al.'s "
        "model.\n# The exponents (about 3-4 times the Lafortune ones of the same material) suggest the fits were "
        "made with\n# cos(theta_h); bench/published.py follows BBM, as for every model here."),
    "cooktorrance_ngan2005": _ngan(
        "NganCookTorrance", "ngan_cooktorrance", [("eta", "F0"), ("roughness", "m")],
        'of the Cook-Torrance specular lobe (R. L. Cook, K. E. Torrance, "A reflectance model for computer '
        'graphics",\n# ACM TOG 1(1), 1982) with a Lambertian term',
        "Aggregate(Lambertian(albedo=kd), NganCookTorrance(albedo=ks, eta=F0, roughness=m))",
        ["#   f(wi, wo) = kd / pi + ks * D(h) * G * F(cd) / (pi * cos(theta_i) * cos(theta_o))", _KD, _KS,
         "#   F0                 Schlick Fresnel F(c) = F0 + (1 - F0)(1 - c)^5 at cd = cos(theta_d), the mean of "
         "wi.h and wo.h;\n#                      BBM names it eta, but it is the reflectance at normal incidence "
         "(ior::reflectance), unitless",
         "#   m                  Beckmann roughness: D(h) = exp(-tan^2(theta_h) / m^2) / (pi m^2 cos^4(theta_h)), "
         "unitless",
         "#   G                  V-groove shadowing min(1, 2 cos(theta_h) cos(theta_i) / wi.h, 2 cos(theta_h) "
         "cos(theta_o) / wo.h)"],
        "# BBM: include/bsdfmodel/ngan.h (ngancooktorrance), microfacet.h, ndf/beckmann.h,\n"
        "# maskingshadowing/vgroove.h, bbm/fresnel_schlick.h."),
    "he_ngan2005": _ngan(
        "NganHe", "ngan_he", [("autocorrelation", "tau"), ("roughness", "sigma"), ("eta", "eta")],
        'of the directional specular term of the He-Torrance-Sillion-Greenberg model (X. D. He, K. E. Torrance,\n'
        '# F. X. Sillion, D. P. Greenberg, "A comprehensive physical model for light reflection", SIGGRAPH 1991) '
        'with a\n# Lambertian term',
        "Aggregate(Lambertian(albedo=kd), NganHe(albedo=ks, autocorrelation=tau, roughness=sigma, eta))",
        ["#   f(wi, wo) = kd / pi + ks * F(c) * S(wi) S(wo) * G * D / (pi cos(theta_i) cos(theta_o)),  c = "
         "sqrt((1 + wi.wo) / 2)", _KD, _KS,
         "#   tau                surface autocorrelation length in micrometres",
         "#   sigma              RMS surface roughness in micrometres",
         "#   eta                index of refraction of the exact unpolarised dielectric Fresnel F (Cook-Torrance "
         "form)",
         "#   S, G, D            He et al.'s shadowing (eqs. 24-25 with the errata's exponential), geometrical "
         "factor (eq. 76)\n#                      and Taylor-series distribution (eqs. 78-84, Westin et al.'s form "
         "of eq. 78), per channel at\n#                      BBM's wavelengths (0.645, 0.526, 0.444) micrometres "
         "for (R, G, B); see bench/published.py"],
        "# BBM: include/bsdfmodel/ngan.h (nganhe: he_base with fresnel::cook, he_eq25::Errata, he_eq78::Westin, "
        "4 Newton steps,\n# up to 64 adaptive Taylor terms, the rough approximation above g = 18), he.h."),
    "lafortune_ngan2005": _ngan(
        "NganLafortune", "ngan_lafortune", [("Cxy", "Cxy"), ("Cz", "Cz"), ("sharpness", "n")],
        'of the isotropic one-lobe Lafortune model (E. P. F. Lafortune, S.-C. Foo, K. E. Torrance, D. P. Greenberg,\n'
        '# "Non-linear approximation of reflectance functions", SIGGRAPH 1997) with a Lambertian term',
        "Aggregate(Lambertian(albedo=kd), NganLafortune(albedo=ks, Cxy, Cz, sharpness=n))",
        ["#   f(wi, wo) = kd / pi + ks * (n + 2) / (2 pi) * max(Cxy (x_i x_o + y_i y_o) + Cz z_i z_o, 0)^n "
         "/ max(Cz^2, Cxy^2)^(n/2)", _KD, _KS,
         "#   Cxy, Cz            lobe coefficients, unitless (Cxy < 0: a lobe around the mirror direction)",
         "#   n                  exponent, unitless (up to 16600: the two powers under- and overflow in float64; "
         "BBM's doubleRGB\n#                      evaluation gives NaN there, its long double one does not)"],
        "# BBM: include/bsdfmodel/ngan.h (nganlafortune: Lafortune times Ngan's normalisation), lafortune.h."),
    "ward_ngan2005": _ngan(
        "NganWard", "ngan_ward", [("roughness", "alpha")],
        'of the isotropic Ward model (G. J. Ward, "Measuring and modeling anisotropic reflection", SIGGRAPH 1992)\n'
        '# with a Lambertian term',
        "Aggregate(Lambertian(albedo=kd), NganWard(albedo=ks, roughness=alpha))",
        ["#   f(wi, wo) = kd / pi + ks * exp(-tan^2(theta_h) / alpha^2) / (4 pi alpha^2 sqrt(cos theta_i cos "
         "theta_o))", _KD, _KS, "#   alpha              roughness, unitless"],
        "# BBM: include/bsdfmodel/ngan.h (nganward), ward.h."),
    "wardduer_ngan2005": _ngan(
        "NganWardDuer", "ngan_wardduer", [("roughness", "alpha")],
        'of the isotropic Ward model with Dür\'s normalisation (A. Dür, "An improved normalization for the Ward '
        'reflectance\n# model", Journal of Graphics Tools 11(1), 2006) with a Lambertian term',
        "Aggregate(Lambertian(albedo=kd), NganWardDuer(albedo=ks, roughness=alpha))",
        ["#   f(wi, wo) = kd / pi + ks * exp(-tan^2(theta_h) / alpha^2) / (4 pi alpha^2 cos theta_i cos theta_o)",
         _KD, _KS, "#   alpha              roughness, unitless"],
        "# BBM: include/bsdfmodel/ngan.h (nganwardduer), wardduer.h."),
})

_LINE = re.compile(r"^(?P<name>\S+) = Aggregate\(Lambertian\(albedo = \[(?P<kd>[^\]]*)\]\), "
                   r"(?P<cls>\w+)\((?P<args>.*)\)\)\s*$")
_ARG = re.compile(r"(\w+) = (\[[^\]]*\]|[^,\s]+)")


def parse(text: str, cls: str) -> dict[str, dict[str, str]]:
    """material -> {attribute: number text, or a list of number texts for a bracketed value}, ``kd`` the
    Lambertian albedo; every non-comment line must be an Aggregate of a Lambertian and ``cls``."""
    out = {}
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        m = _LINE.match(line)
        if not m or m["cls"] != cls:
            raise ValueError(f"unexpected line for {cls}: {line[:120]}")
        args = {k: [x.strip() for x in v[1:-1].split(",")] if v.startswith("[") else v
                for k, v in _ARG.findall(m["args"])}
        args["kd"] = [x.strip() for x in m["kd"].split(",")]
        out[m["name"]] = args
    return out


def write(model: str, text: str, commit: str) -> int:
    spec = SPECS[model]
    fits = parse(text, spec["cls"])
    metric = f' ("{spec["metric"]}" metric)' if spec["metric"] else ""
    what = spec["what"].replace(f'("{spec["metric"]}" metric) ', "") if spec["metric"] else spec["what"]
    head = [f"# Published per-material fits{metric} {what}, to {len(fits)} MERL materials:",
            f"# {spec['paper']}",
            f"# Source: https://github.com/bsdfbenchmark/bbm commit {commit}, path fits/{spec['fit']}.fit", "#",
            "# Numbers copied verbatim (same digits) from the BBM fit file named above, which holds them as",
            f'# "{spec["form"]}".',
            f'# Evaluated by bench/published.py (model "{model}"). One row per MERL material (MERL\'s names, as BBM '
            "spells them):",
            *spec["lines"], spec["notes"], spec["scale"]]
    if spec["metric"]:
        head.append(_E[spec["metric"]])
    columns = ["kd_r", "kd_g", "kd_b", "ks_r", "ks_g", "ks_b"] + [c for _, c in spec["attrs"]]
    rows = [",".join(columns)]
    for material in sorted(fits):
        a = fits[material]
        if len(a["kd"]) != 3 or len(a["albedo"]) != 3 or set(a) != {"kd", "albedo", *(k for k, _ in spec["attrs"])}:
            raise ValueError(f"{model} {material}: unexpected attributes {sorted(a)}")
        values = [*a["kd"], *a["albedo"], *(a[k] for k, _ in spec["attrs"])]
        for v in values:
            float(v)                                          # every field a number
        rows.append(",".join([material, *values]))
    rows[0] = "material," + rows[0]
    (OUT / f"{model}.csv").write_text("\n".join(head) + "\n" + "\n".join(rows) + "\n")
    return len(fits)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bbm", type=Path, help="BBM git directory, or a folder with the .fit files (then --commit)")
    ap.add_argument("--commit", help="BBM commit the .fit files are from (default: the git directory's HEAD)")
    args = ap.parse_args()
    folder = not (args.bbm / "HEAD").exists() and not (args.bbm / ".git").exists()
    commit = args.commit or subprocess.run(["git", "-C", str(args.bbm), "rev-parse", "HEAD"], check=True,
                                           capture_output=True, text=True).stdout.strip()
    for model, spec in SPECS.items():
        if folder:
            text = (args.bbm / f"{spec['fit']}.fit").read_text()
        else:
            text = subprocess.run(["git", "-C", str(args.bbm), "show", f"{commit}:fits/{spec['fit']}.fit"], check=True,
                                  capture_output=True, text=True).stdout
        print(f"{model}: {write(model, text, commit)} materials")


if __name__ == "__main__":
    main()
