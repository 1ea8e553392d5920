"""Which form a reflection lobe takes: its NDF and its Fresnel term, chosen per material.

The talk fixes the lobes (diffuse, diffraction, Cook-Torrance) but not the form of the
Cook-Torrance lobe: a highlight with a power-law tail wants a heavy-tailed NDF (GTR), a coated
dielectric a dielectric Fresnel.  ``form_variants`` rewrites a model with every candidate form of
its reflection lobes (the shadowing word kept: ``smith`` becomes the chosen NDF's own Smith term);
each is fitted, and the form is chosen by the penalised error of the lobe comparison
(brdfcl.optim.selection): rmse_log x (1 + 0.02 x free parameters), so a form with an extra
parameter (GTR's tail exponent) is kept only where it earns it, and a form with fewer (one
refractive index instead of an F0 per channel) wins ties.  A form whose NDF contains another's
(``NESTED``: GTR at gamma = 2 is GGX) starts from that form's fits instead of a global search.
"""
from __future__ import annotations

import numpy as np

from brdfcl.model.compose import Model, ModelError, parse_lobe
from brdfcl.optim.selection import select

NDF_FORMS = ("ggx", "gtr", "beckmann")
FRESNEL_FORMS = ("schlick", "dielectric")
NESTED = {"gtr": ("ggx", {"gamma": 2.0})}
"""NDFs that contain another at a parameter value (GTR at gamma = 2 is GGX): a form with such an NDF
is refined from the fits of the contained form with the same Fresnel (a warm start, no global
search): it starts at that form's optimum (a failed contained fit gives no start)."""


def parse_forms(text: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """``NDF[,NDF...][:FRESNEL[,FRESNEL...]]`` (e.g. ``ggx,gtr:schlick,dielectric``) as (NDFs,
    Fresnels); a part left out keeps the model's own.  ModelError names an unknown word."""
    from brdfcl.model.terms import REGISTRY
    ndf_text, _, fresnel_text = text.partition(":")
    ndfs = tuple(w.strip().lower() for w in ndf_text.split(",") if w.strip())
    fresnels = tuple(w.strip().lower() for w in fresnel_text.split(",") if w.strip())
    for words, kind in ((ndfs, "ndf"), (fresnels, "fresnel")):
        bad = [w for w in words if w not in REGISTRY[kind]]
        if bad:
            raise ModelError(f"forms '{text}': unknown {kind} {', '.join(bad)}; valid: {', '.join(REGISTRY[kind])}")
    return ndfs, fresnels


def form_variants(spec: str, ndfs=NDF_FORMS, fresnels=FRESNEL_FORMS) -> dict[str, str]:
    """{'ndf:fresnel': model spec}: ``spec`` with every reflection lobe given that NDF and Fresnel
    (empty ``ndfs`` / ``fresnels``: the lobe's own), the candidates exactly as asked.  ModelError
    when a candidate cannot be built (a shadowing not defined for that NDF: the message says which)."""
    lobes = Model(spec).spec.split("+")
    own = [parse_lobe(t).spec().split(":") for t in lobes if parse_lobe(t).role == "reflection"]
    if not own:
        raise ModelError(f"'{spec}' has no reflection lobe whose form could be chosen")
    out = {}
    for ndf in ndfs or (own[0][0],):
        for fresnel in fresnels or (own[0][2],):
            parts, words = [], set()
            for text in lobes:
                if parse_lobe(text).role == "reflection":
                    _, shadowing, _ = parse_lobe(text).spec().split(":")
                    parts.append(f"{ndf}:{shadowing}:{fresnel}")
                    words.add(shadowing)
                else:
                    parts.append(text)
            try:
                out[f"{ndf}:{fresnel}"] = Model("+".join(parts)).spec
            except ModelError:
                raise ModelError(f"form {ndf}:{fresnel} of '{spec}': {ndf} has no {' or '.join(sorted(words))} "
                                 f"shadowing; leave {ndf} out of --forms or give the model another shadowing "
                                 f"(e.g. :vcavity)") from None
    return out


def choose_form(errors: dict, specs: dict) -> tuple[str, dict]:
    """The form with the lowest penalised error: (key, {key: penalised error}), as
    brdfcl.optim.selection.select (``errors``: rmse_log by form key, ``specs``: their models)."""
    return select(errors, specs)


def nesting_order(key: str) -> tuple[int, str]:
    """Sort key of form keys ('ndf:fresnel'): a contained form before the forms that contain it."""
    return (int(key.split(":")[0] in NESTED), key)


def nested_source(key: str, fitted) -> str | None:
    """The fitted form ``key`` ('ndf:fresnel') is refined from, if any (its NDF contains that form's)."""
    ndf, _, fresnel = key.partition(":")
    if ndf not in NESTED:
        return None
    source = f"{NESTED[ndf][0]}:{fresnel}"
    return source if source in fitted else None


def warm_start(source_results, model: Model) -> np.ndarray:
    """Start values (n, ``model``'s parameters) from the fits of a contained form: shared
    parameters copied, the containing NDF's own at the values where it equals the contained one,
    the model's defaults where a source value is not finite."""
    extra = {f".{p}": v for nested in NESTED.values() for p, v in nested[1].items()}
    rows = []
    for r in source_results:
        row = []
        for n in model.names:
            if n in r.params:
                row.append(r.params[n])
            else:
                row.append(next((v for suffix, v in extra.items() if n.endswith(suffix)), np.nan))
        rows.append(row)
    x = np.array(rows, dtype=np.float64).reshape(len(rows), len(model.names))
    return np.where(np.isfinite(x), x, model.defaults()[None, :])
