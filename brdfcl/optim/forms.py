"""Which form a reflection lobe takes: its NDF and its Fresnel term, chosen per material.

The talk fixes the lobes (diffuse, diffraction, Cook-Torrance) but not the form of the
Cook-Torrance lobe: a highlight with a power-law tail wants a heavy-tailed NDF (GTR, ABC), a
coated dielectric a dielectric Fresnel.  ``form_variants`` rewrites a model with every candidate
form of its reflection lobes (the shadowing word kept: ``smith`` becomes the chosen NDF's own Smith
term, unless a form names its own); ``FormFitter`` fits a batch in each and keeps, per material,
the form of least penalised error (brdfcl.optim.selection): rmse_log x (1 + 0.02 x free parameters), so a form with more
parameters is kept only where it earns them, and one with fewer (one refractive index instead of
an F0 per channel) wins ties.  A form that can start from another's fits (``STARTS``: GTR at
gamma = 2 is GGX; ABC near its peak is a GTR) is refined from them, without a global search.  On a
table every form is first fitted on the preview cells only, and one far behind a material's best
there (``SCREEN``) is not fitted on its full table (`screen`); a start may be taken only from some
of its source's fits (``GATES``: Beckmann only from an ABC fit whose tail is light enough), the
other materials not fitted in that form at all.

``DEFAULT_FORMS`` is what ``brdfcl fit-all`` chooses among when no model is given: the forms a
default needs so that no development proxy is fitted worse than by the published SGD and ABC fits
(bench/bench_forms.py; the comparison is bench/results/forms_published.md) and the common analytic
families (GGX and Beckmann metals, Cook-Torrance's V-cavity form) are inside it.
"""
from __future__ import annotations

import dataclasses
import difflib
import logging
import re
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import replace

import numpy as np

from brdfcl._words import count
from brdfcl.model.compose import Model, ModelError, parse_lobe
from brdfcl.optim.assessment import assess, traded
from brdfcl.optim.fit import Begun, FitOptions, FitResult, Fitter, same_cells
from brdfcl.optim.selection import penalised, select

_log = logging.getLogger("brdfcl")
NDF_FORMS = ("ggx", "gtr", "beckmann")
FRESNEL_FORMS = ("schlick", "dielectric")
DEFAULT_FORMS = "gtr:dielectric,abc:schlick,gtr:schlick,beckmann:schlick,beckmann:vcavity:schlick"
"""GTR with a dielectric Fresnel (its own global search), then from its fits ABC and GTR with
Schlick's (an F0 per channel: GGX metals are GTR at gamma = 2), Beckmann from the ABC fits, and
Cook & Torrance's own form (Beckmann, V-cavity shadowing) from the Beckmann fits."""


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
            close = difflib.get_close_matches(bad[0], list(REGISTRY[kind]), n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise ModelError(f"forms '{text}': unknown {kind.upper() if kind == 'ndf' else kind} {', '.join(bad)}"
                             f"{hint}; valid: {', '.join(REGISTRY[kind])}")
    return ndfs, fresnels


def form_keys(spec: str, text: str) -> dict[str, str]:
    """{form key: model spec} for a ``--forms`` text: a list of NDF:FRESNEL pairs
    (``gtr:dielectric,abc:schlick``) or NDF:SHADOWING:FRESNEL triples (``beckmann:vcavity:schlick``,
    the shadowing given instead of the model's own), or every NDF with every Fresnel
    (``NDF[,NDF...][:FRESNEL[,...]]``, a part left out keeping the model's own).  ModelError names an
    unknown word or an impossible form."""
    from brdfcl.model.terms import REGISTRY
    if not text.strip():
        raise ModelError("forms '': give NDF:FRESNEL pairs (gtr:dielectric,abc:schlick), NDFS[:FRESNELS] or none")
    if text.count(":") > 1:
        forms = [w.strip().lower().split(":") for w in text.split(",") if w.strip()]
        if any(len(p) not in (2, 3) or not all(p) for p in forms):
            raise ModelError(f"forms '{text}': a list of NDF:FRESNEL pairs or NDF:SHADOWING:FRESNEL triples, "
                             "or NDFS[:FRESNELS]")
        out = {}
        for form in forms:
            shadowing = None
            if len(form) == 3:
                shadowing = form.pop(1)
                if shadowing not in REGISTRY["shadowing"]:
                    raise ModelError(f"forms '{text}': unknown shadowing {shadowing}; valid: "
                                     f"{', '.join(REGISTRY['shadowing'])}")
            out.update(form_variants(spec, *parse_forms(":".join(form)), shadowing=shadowing))
        return out
    return form_variants(spec, *parse_forms(text))


def form_variants(spec: str, ndfs=NDF_FORMS, fresnels=FRESNEL_FORMS, shadowing: str | None = None) -> dict[str, str]:
    """{'ndf:fresnel': model spec}: ``spec`` with every reflection lobe given that NDF and Fresnel
    (empty ``ndfs`` / ``fresnels``: the lobe's own), the candidates exactly as asked; with
    ``shadowing``, every lobe's shadowing replaced too and the keys 'ndf:shadowing:fresnel'.
    ModelError when a candidate cannot be built (a shadowing not defined for that NDF: the message
    says which)."""
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
                    _, own_shadowing, _ = parse_lobe(text).spec().split(":")
                    parts.append(f"{ndf}:{shadowing or own_shadowing}:{fresnel}")
                    words.add(shadowing or own_shadowing)
                else:
                    parts.append(text)
            key = f"{ndf}:{fresnel}" if shadowing is None else f"{ndf}:{shadowing}:{fresnel}"
            try:
                out[key] = Model("+".join(parts)).spec
            except ModelError:
                raise ModelError(f"form {key} of '{spec}': {ndf} has no {' or '.join(sorted(words))} "
                                 f"shadowing; leave {ndf} out of --forms or give the model another shadowing "
                                 f"(e.g. :vcavity)") from None
    return out


DROP_TIE = 0.005
"""A diffraction lobe whose amplitude trades places with the diffuse's (the assessment's flag) is
left out where the fit without it has an rmse_log at most this much (relative) above: the data
then do not tell a flat halo from the diffuse, and the diffuse alone is the simpler account."""

SCREEN = 0.02
"""A form whose penalised error on the preview cells exceeds a material's least by more than this
(relative) is not fitted on that material's full table: the full-table stage changes an error
converged on the preview by far less (its iterations are capped, `FitOptions.preview_final_iter`).
On the 80 MERL proxies, every form fitted in full, a form within 10% of the best on the preview
closed at most 0.2% of its gap on the full table (docs/fitting.md)."""

BEHIND = 0.05
"""A form's preview run stops for a material (brdfcl.optim.lm.BEHIND_AFTER iterations in, not yet
converged) where its penalised error is more than this above the least of the forms already on
the preview cells: wider than SCREEN, as its error may still fall."""


def screen(estimates: dict, specs: dict, n: int) -> dict:
    """{form: (n,) bool}: the forms each material is fitted in on its full table, from their
    errors on the preview cells (``estimates``: {form: (n,)}) penalised as `choose_form`; a material
    with no finite estimate keeps every form."""
    keep = {k: np.ones(n, dtype=bool) for k in estimates}
    for i in range(n):
        errs = {k: float(e[i]) for k, e in estimates.items() if np.isfinite(e[i])}
        if not errs:
            continue
        _, pen = choose_form(errs, specs)
        best = min(pen.values())
        for k in estimates:
            keep[k][i] = k in pen and pen[k] <= best * (1 + SCREEN)
    return keep


def choose_form(errors: dict, specs: dict) -> tuple[str, dict]:
    """The form with the lowest penalised error: (key, {key: penalised error}), as
    brdfcl.optim.selection.select (``errors``: rmse_log by form key, ``specs``: their models)."""
    return select(errors, specs)


# ---- warm starts: a form refined from another form's fits ----------------------------------------

def _rows(params: Sequence[dict], model: Model) -> np.ndarray:
    """Start values (n, ``model``'s parameters) from parameter dicts: clipped to the bounds, the
    model's defaults where a value is missing or not finite."""
    x = np.array([[p.get(n, np.nan) for n in model.names] for p in params], dtype=np.float64)
    x = np.clip(x.reshape(len(params), len(model.names)), model.lo, model.hi)
    return np.where(np.isfinite(x), x, model.defaults()[None, :])


def f0_of_eta(eta):
    """A dielectric's reflectance at normal incidence, ((eta - 1) / (eta + 1))^2."""
    return ((eta - 1) / (eta + 1)) ** 2


def _f0_channels(names, lobe: str) -> list[str]:
    return [m.group(1) for n in names for m in [re.fullmatch(rf"{re.escape(lobe)}\.F0_(\w+)", n)] if m]


def _lobes(model: Model) -> list[str]:
    """The prefixes of the model's reflection lobes (``ct``, ``ct2``, ...): a form is every one's."""
    return [lb.prefix for lb in model.lobes if lb.role == "reflection"]


def _convert(source_results, model: Model, lobe_fn: Callable[[dict, str, Model], None]) -> np.ndarray:
    """Start rows from fits: each fit's parameters, ``lobe_fn(params, prefix, model)`` applied to
    every reflection lobe in place."""
    params = []
    for r in source_results:
        p = dict(r.params)
        for lobe in _lobes(model):
            lobe_fn(p, lobe, model)
        params.append(p)
    return _rows(params, model)


def _gamma_two(p: dict, lobe: str, model: Model) -> None:
    p[f"{lobe}.gamma"] = 2.0


def _eta_from_f0(p: dict, lobe: str, model: Model) -> None:
    channels = _f0_channels(list(p), lobe)
    if not channels:
        return
    k = model.names.index(f"{lobe}.eta")
    f0 = np.array([p.pop(f"{lobe}.F0_{c}") for c in channels])
    s = np.sqrt(np.clip(f0.mean(), 1e-6, 0.999))
    p[f"{lobe}.eta"] = eta = float(np.clip((1 + s) / (1 - s), model.lo[k], model.hi[k]))
    for c, f in zip(channels, f0):
        p[f"{lobe}.rho_{c}"] *= f / f0_of_eta(eta)


def _abc_from_gtr(p: dict, lobe: str, model: Model) -> None:
    alpha, gamma = p.pop(f"{lobe}.alpha"), p.pop(f"{lobe}.gamma")
    p[f"{lobe}.B"], p[f"{lobe}.C"] = 2.0 / (alpha * alpha), gamma
    if f"{lobe}.eta" in p and f"{lobe}.eta" not in model.names:        # a Schlick ABC: F0 from eta
        f0 = f0_of_eta(p.pop(f"{lobe}.eta"))
        p.update({f"{lobe}.F0_{c}": f0 for c in _f0_channels(model.names, lobe)})


def _schlick_from_eta(p: dict, lobe: str, model: Model) -> None:
    eta = p.pop(f"{lobe}.eta", None)
    if eta is not None:
        p.update({f"{lobe}.F0_{c}": f0_of_eta(eta) for c in _f0_channels(model.names, lobe)})


def _beckmann_from_abc(p: dict, lobe: str, model: Model) -> None:
    b, c = p.pop(f"{lobe}.B"), p.pop(f"{lobe}.C")
    p[f"{lobe}.alpha"] = float(np.sqrt(2.0 / (b * c)))


def same_parameters(source_results, model: Model) -> np.ndarray:
    """A start from fits whose parameters are this model's (another shadowing of the same NDF and
    Fresnel): copied."""
    return _convert(source_results, model, lambda p, lobe, m: None)


def warm_start(source_results, model: Model) -> np.ndarray:
    """GTR from GGX fits with the same Fresnel: the shared parameters copied, gamma = 2 (where GTR
    is GGX)."""
    return _convert(source_results, model, _gamma_two)


def dielectric_from_schlick(source_results, model: Model) -> np.ndarray:
    """A dielectric-Fresnel form from the same NDF with Schlick's: eta from the mean F0
    (F0 = ((eta - 1) / (eta + 1))^2, clipped to eta's bounds), each channel's amplitude scaled so that
    rho x F at normal incidence is kept; the rest copied."""
    return _convert(source_results, model, _eta_from_f0)


def abc_from_gtr(source_results, model: Model) -> np.ndarray:
    """ABC from GTR fits: near the peak 1 - cos th ~ th^2 / 2 and tan^2 th ~ th^2, so
    (1 + tan^2 / alpha^2)^-gamma ~ (1 + B (1 - cos th))^-C at B = 2 / alpha^2, C = gamma (the tails
    match too: th^-2 gamma); the Fresnel kept, or, for a Schlick ABC from a dielectric GTR, eta's
    F(0) as every channel's F0 (the same F at normal incidence)."""
    return _convert(source_results, model, _abc_from_gtr)


def schlick_from_dielectric(source_results, model: Model) -> np.ndarray:
    """A Schlick form from the same NDF with a dielectric Fresnel: eta's F(0) as every channel's F0
    (the same F at normal incidence; each channel's F0 then free); the rest copied."""
    return _convert(source_results, model, _schlick_from_eta)


def beckmann_from_abc(source_results, model: Model) -> np.ndarray:
    """Beckmann from ABC fits: as C grows (1 + B (1 - cos th))^-C tends to exp(-B C (1 - cos th)),
    and near the peak B C (1 - cos th) ~ B C th^2 / 2 against Beckmann's tan^2 th / alpha^2 ~
    th^2 / alpha^2, so alpha = sqrt(2 / (B C)); the Fresnel kept."""
    return _convert(source_results, model, _beckmann_from_abc)


STARTS: tuple[tuple[str, str, Callable], ...] = (
    # (form, the form whose fits it starts from ('*': the same word), conversion); the first whose
    # source was fitted, every fit a success, gives the start
    ("gtr:*", "ggx:*", warm_start),
    ("abc:schlick", "gtr:dielectric", abc_from_gtr),
    ("abc:*", "gtr:*", abc_from_gtr),
    ("*:dielectric", "*:schlick", dielectric_from_schlick),
    ("*:schlick", "*:dielectric", schlick_from_dielectric),
    ("beckmann:*", "abc:*", beckmann_from_abc),
)


def _sources(key: str) -> list[tuple[str, Callable]]:
    """The forms ``key`` could start from, in STARTS' order, with their conversions; a form with its
    own shadowing (``ndf:shadowing:fresnel``) starts first from the same NDF and Fresnel with the
    model's shadowing (the same parameters, copied)."""
    if key.count(":") == 2:
        ndf, _, fresnel = key.split(":")
        return [(f"{ndf}:{fresnel}", same_parameters)] + _sources(f"{ndf}:{fresnel}")
    ndf, fresnel = key.split(":")
    out = []
    for target, source, how in STARTS:
        t_ndf, t_fresnel = target.split(":")
        if t_ndf in ("*", ndf) and t_fresnel in ("*", fresnel):
            s_ndf, s_fresnel = source.split(":")
            s = f"{ndf if s_ndf == '*' else s_ndf}:{fresnel if s_fresnel == '*' else s_fresnel}"
            if s != key:
                out.append((s, how))
    return out


def start_source(key: str, fitted: dict, tried: dict | None = None) -> tuple[str, Callable] | None:
    """(form, conversion) whose fits ``key`` starts from, among ``fitted`` ({key: results}); None:
    its own global search (no source fitted, or one of its fits failed).  ``tried`` ({key: (n,)
    bool}): the materials each form was fitted for; only those fits need to be successes."""
    for source, how in _sources(key):
        if source in fitted:
            asked = (tried or {}).get(source)
            if all(r.success for k, r in enumerate(fitted[source]) if asked is None or asked[k]):
                return source, how
    return None


BECKMANN_TAIL = 4.0
"""An ABC fit whose tail exponent C is below this on any reflection lobe starts no Beckmann form:
ABC's D tends to Beckmann's as C grows (`beckmann_from_abc`), and a C that settles well inside
its range (0.25 to 8) is a tail heavier than Beckmann's Gaussian.  On the 80 MERL proxies every
Beckmann form started from an ABC fit with C < 4 was 6% or more behind the material's best form on
the preview cells (the screen keeps forms within 2%); the demo's Beckmann materials fit at C = 8,
the bound (docs/fitting.md)."""


def _tail_light(params: dict, model: Model) -> bool:
    return all(params[f"{lobe}.C"] >= BECKMANN_TAIL for lobe in _lobes(model) if f"{lobe}.C" in params)


GATES: dict[Callable, tuple[Callable[[dict, Model], bool], str]] = {
    beckmann_from_abc: (_tail_light, f"the ABC fit's tail exponent is below {BECKMANN_TAIL:g}")}
"""Conversions that start a form only from some of their source's fits: (``gate(source params,
source model)``, why a material it refuses is left out); the other materials are not fitted in
that form (on tables, where the preview cells decide which forms go on)."""


def worth_starting(how: Callable, source_results, source_model: Model) -> np.ndarray:
    """(n,) bool: the materials whose fits in the source form the conversion ``how`` starts from."""
    gate = GATES[how][0] if how in GATES else None
    return np.array([gate is None or gate(r.params, source_model) for r in source_results], dtype=bool)


def fit_order(keys) -> list[str]:
    """``keys`` with every form after the forms among them it could start from.  Where forms could
    start from each other (a Schlick and a dielectric form of one NDF), the one that can start from
    a form already placed goes first, else the one waiting on the fewest, else the first in ``keys``."""
    todo, order = list(keys), []
    while todo:
        def rank(k: str) -> tuple:
            sources = [s for s, _ in _sources(k)]
            pending = sum(s in todo for s in sources)
            return (pending > 0, not any(s in order for s in sources), pending, todo.index(k))
        order.append(min(todo, key=rank))
        todo.remove(order[-1])
    return order


def asked_for(forms: str | None) -> bool:
    """Whether ``forms`` names candidates itself (not the default choice, not none)."""
    return forms not in (None, "default") and forms.strip().lower() != "none"


def resolve(forms: str | None, opts: FitOptions, model_given: bool = False) -> str | None:
    """The candidate forms a run chooses among: ``"default"`` is DEFAULT_FORMS for FitOptions'
    default model, not asked for by name (``model_given``), with nothing fixed, else none (the model
    as given); None or ``"none"``: none."""
    if forms == "default":
        default = opts.model == FitOptions().model and not model_given and not opts.fixed
        return DEFAULT_FORMS if default else None
    return forms if asked_for(forms) else None


@contextmanager
def _unassessed(f: Fitter):
    """``f``'s fits finish without their assessment (only the chosen form's is assessed, by
    `FormFitter`), its setting kept for that."""
    keep, f.assess_results = f.assess_results, False
    try:
        yield f
    finally:
        f.assess_results = keep


class FormFitter:
    """Fits a batch in every candidate form (``forms``: {key: model spec}, `form_keys`) and keeps
    each material's form of least penalised error; every form fits the same cells, read once.
    Only the chosen fit of a material is assessed (standard errors, albedo, flags): the others are
    thrown away.  ``drop_traded``: a chosen fit's diffraction lobe that trades places with the
    diffuse is left out where the data allow (`_drop_traded`); off where another test decides the
    lobes (--select-lobes)."""

    def __init__(self, opts: FitOptions, forms: dict[str, str], lambdas: Sequence[float] | None = None,
                 drop_traded: bool = True):
        self.forms, self.lambdas, self.drop_traded = dict(forms), lambdas, drop_traded
        self.fitters = {k: Fitter(replace(opts, model=s), lambdas=lambdas) for k, s in self.forms.items()}

    def fit(self, measurements: Sequence, on_result: Callable[[FitResult, dict], None] | None = None,
            log: Callable[[str], None] = lambda s: None,
            on_error: Callable | None = None) -> list[tuple[FitResult, dict]]:
        """[(the chosen form's fit, what NAME.json records of the choice: ``form``, ``form_errors``)]
        per measurement that could be read (the others go to ``on_error``), in order;
        ``on_result(result, record)`` as each is chosen.  A material whose every form failed keeps
        the first form's (failed) fit."""
        measurements = list(measurements)
        first: list = []

        def upload(f: Fitter) -> tuple:
            b = f.load(measurements if not first else [measurements[k] for k in first[0]],
                       on_error if not first else None)
            if not first:
                first.append(b.read)
            return b.names, b.targets, b.data
        return self._choose(upload, on_result, log)

    def _choose(self, upload: Callable, on_result, log) -> list[tuple[FitResult, dict]]:
        """``upload(fitter)``: (names, targets, data) of the batch on that fitter's engine, made once
        for the forms whose engines can read the same buffers (`same_cells`).

        Every form is taken to its full-table stage first (`Fitter.begin`: its global search or a
        warm start from another form, then the preview cells); a form whose penalised error there
        is more than SCREEN above a material's best is not fitted on that material's full table
        (`screen`).  Without a preview set (scattered samples) every form is fitted in full."""
        n = -1
        sources: dict[str, list] = {}
        tried: dict[str, np.ndarray] = {}      # the materials each form is fitted for
        why: dict[str, str] = {}               # why a form left materials out
        begun: dict[str, Begun] = {}
        full: dict[str, list] = {}
        uploaded: dict[str, tuple] = {}
        for key in fit_order(self.forms):
            f = self.fitters[key]
            src = start_source(key, sources, tried)
            start = None if src is None else src[1](sources[src[0]], f.model)
            same = next((k for k in uploaded if same_cells(self.fitters[k], f)), None)
            names, targets, data = uploaded[key] = uploaded[same] if same is not None else upload(f)
            n = len(names)
            if not n:
                return []
            tried[key] = np.ones(n, dtype=bool)
            if src is not None and targets.preview is not None:
                tried[key] = tried[src[0]] & worth_starting(src[1], sources[src[0]], self.fitters[src[0]].model)
            mats = None if tried[key].all() else np.flatnonzero(tried[key])
            b = f.begin(names, targets, data, time.perf_counter(), log=log, start_values=start,
                        ceiling=self._ceiling(key, begun, n), mats=mats)
            if b.previewed is None:
                with _unassessed(f):
                    full[key] = f.complete(b, log=log)
                sources[key] = full[key]
            else:
                begun[key] = b
                sources[key] = b.starts()
            left = n - int(tried[key].sum())
            if left and src is not None:
                why[key] = GATES[src[1]][1] if src[1] in GATES else f"no {src[0]} fit to start from"
            notes = (["no global search"] if src else []) + ([f"{left} left out: {why[key]}"] if key in why else [])
            log(f"form {key}: fitted {count(n - left, 'material')}{'' if key in full else ' on the preview cells'}"
                + (f" from the {src[0]} fits" if src else "") + (f" ({'; '.join(notes)})" if notes else ""))
        estimates = {k: e for k, b in begun.items() if (e := b.estimate()) is not None}
        kept = screen(estimates, self.forms, n)
        fitted: dict[str, list] = {k: list(v) for k, v in full.items()}
        for key, b in begun.items():
            rows = np.flatnonzero(kept[key])
            f = self.fitters[key]
            with _unassessed(f):
                done = f.complete(b, log=log, mats=rows)
            fitted[key] = [None] * n
            for row, r in zip(rows, done):
                fitted[key][int(row)] = r
            log(f"form {key}: fitted {count(rows.size, 'material')} on the full table"
                + (f" ({n - rows.size} left out: more than {SCREEN:.0%} worse on the preview cells)"
                   if rows.size < n else ""))
        chosen, records = [], []
        for i in range(n):
            errors = {k: fitted[k][i].errors["rmse_log"] for k in self.forms
                      if fitted[k][i] is not None and fitted[k][i].success
                      and np.isfinite(fitted[k][i].errors["rmse_log"])}
            record: dict
            if errors:
                key, pen = choose_form(errors, self.forms)
                record = {"form": key, "form_errors": {k: {"rmse_log": errors[k], "penalised": pen[k]}
                                                       for k in errors}}
                for k in self.forms:
                    if k not in errors and k in estimates and np.isfinite(estimates[k][i]):
                        _, est = choose_form({k: float(estimates[k][i])}, self.forms)
                        record["form_errors"][k] = {"rmse_preview": float(estimates[k][i]), "penalised": est[k]}
                    elif not tried[k][i]:
                        record["form_errors"][k] = {"not_fitted": why[k]}
            else:
                key = next(k for k in self.forms if fitted[k][i] is not None)
                record = {"form": None, "form_errors": {}}
            chosen.append(key)
            records.append(record)
        judged = self._assess(chosen, fitted, uploaded)
        dropped, refits = self._drop_traded(chosen, fitted, judged, upload, uploaded, log) \
            if self.drop_traded else ({}, {})
        out = []
        for i, key in enumerate(chosen):
            # the choice took every form's fit: its time and evaluations are the material's
            r = fitted[key][i]
            seconds = sum(fitted[k][i].seconds if fitted[k][i] is not None else float(begun[k].batch.share[i])
                          for k in self.forms)
            nfev = sum(fitted[k][i].nfev if fitted[k][i] is not None else int(begun[k].batch.global_nfev[i])
                       for k in self.forms)
            if i in refits:                         # the refit without a traded lobe, kept or not
                seconds, nfev = seconds + refits[i].seconds, nfev + refits[i].nfev
            if i in dropped:
                d, records[i]["dropped"] = dropped[i]
                offset = r.history[-1][0] if r.history else 0.0
                history = list(r.history) + [(t + offset, st, e) for t, st, e in d.history]
                out.append((dataclasses.replace(d, seconds=seconds + judged[i][2], nfev=nfev, history=history,
                                                stages={**r.stages, **judged[i][1],
                                                        "without_lobes": d.stages.get("total", d.seconds)}),
                            records[i]))
            else:
                out.append((dataclasses.replace(r, seconds=seconds + judged[i][2], nfev=nfev,
                                                stages={**r.stages, **judged[i][1]}, **judged[i][0]), records[i]))
            if on_result is not None:
                on_result(*out[-1])
        return out

    def _drop_traded(self, chosen: list[str], fitted: dict, judged: list, upload: Callable, uploaded: dict,
                     log) -> tuple[dict[int, tuple[FitResult, dict]], dict[int, FitResult]]:
        """Materials whose chosen fit has diffraction lobes trading places with the diffuse
        (`traded`): the form fitted again without those lobes, from that fit (no global search).
        Returns ({row: (the fit without them, assessed; what NAME.json records, ``dropped``)} of
        those at most DROP_TIE behind in rmse_log, {row: the refit} of every material refitted,
        kept or not: its time and evaluations are the material's).  A refit that raises costs
        nothing but itself (a warning)."""
        kept: dict[int, tuple[FitResult, dict]] = {}
        refits: dict[int, FitResult] = {}
        groups: dict[tuple[str, tuple[str, ...]], list[int]] = {}
        for i, key in enumerate(chosen):
            r, model = fitted[key][i], self.fitters[key].model
            if r is None or not r.success:
                continue
            role = {lb.prefix: lb.role for lb in model.lobes}
            pairs = traded(judged[i][0].get("flags") or [])
            flagged = sorted({a if role.get(a) == "diffraction" else b for a, b in pairs
                              if {role.get(a), role.get(b)} == {"diffraction", "diffuse"}})
            if flagged:
                groups.setdefault((key, tuple(flagged)), []).append(i)
        for (key, halos), rows_list in groups.items():
            f, rows = self.fitters[key], np.array(rows_list, dtype=int)
            if any(n.split(".", 1)[0] in halos for n in f.opts.fixed):
                log(f"form {key}: {', '.join(halos)} kept where it trades places with the diffuse: "
                    "a parameter of it is fixed")
                continue
            sub = f.model.submodel([lb for lb in f.model.lobes if lb.prefix not in halos])
            try:
                g = Fitter(replace(f.opts, model=sub.spec), lambdas=self.lambdas)
                names, targets, data = uploaded[key] if same_cells(f, g) else upload(g)
                start = np.tile(sub.defaults(), (len(names), 1))
                for i in rows:
                    start[i] = [fitted[key][i].params[n] for n in sub.names]
                b = g.begin(names, targets, data, time.perf_counter(), log=log, start_values=start,
                            mats=rows if targets.preview is not None else None)
                done = g.complete(b, log=log, mats=rows)
            except Exception as e:  # noqa: BLE001 - leaving a lobe out is optional: the chosen fits stand
                _log.warning(f"brdfcl: form {key} without {', '.join(halos)} not fitted: {type(e).__name__}: {e}")
                continue
            for i, r in zip(rows, done):
                refits[int(i)] = r
                before, after = fitted[key][i].errors["rmse_log"], r.errors["rmse_log"]
                if r.success and after <= (1 + DROP_TIE) * before:
                    kept[int(i)] = (r, {"lobes": list(halos), "rmse_log": after, "rmse_log_with": before})
            log(f"form {key}: {count(rows.size, 'material')} with {', '.join(halos)} trading places with the "
                f"diffuse; left out of {sum(int(i) in kept for i in rows)} (at most {DROP_TIE:.1%} worse without it)")
        return kept, refits

    def _ceiling(self, key: str, begun: dict, n: int) -> np.ndarray | None:
        """(n,) the rmse on the preview cells above which form ``key``'s preview run stops (BEHIND,
        wider than `screen`'s rule, so that a form stopped there is screened out), from the forms
        already on them; None before any."""
        best = None
        for k, b in begun.items():
            e = b.estimate()
            if e is not None:
                pen = e * penalised(1.0, self.forms[k])
                best = pen if best is None else np.fmin(best, pen)
        return None if best is None else best * (1 + BEHIND) / penalised(1.0, self.forms[key])

    def _assess(self, chosen: list[str], fitted: dict, uploaded: dict) -> list[tuple[dict, dict, float]]:
        """({uncertainty, albedo, flags}, {"uncertainty": seconds}, the material's share of those
        seconds) per material: each chosen fit assessed on its form's cells, one launch per form
        ({}, {}, 0: the fitters do not assess)."""
        out: list[tuple[dict, dict, float]] = [({}, {}, 0.0)] * len(chosen)
        for key, f in self.fitters.items():
            rows = np.array([i for i, k in enumerate(chosen) if k == key], dtype=int)
            if not f.assess_results or not rows.size:
                continue
            t = time.perf_counter()
            _, targets, data = uploaded[key]
            res = [fitted[key][i] for i in rows]
            values = np.array([[r.params[n] for n in f.model.names] for r in res], dtype=np.float64)
            judged = assess(f.objective, targets.full, data=data, values=values, rows=rows,
                            at_bound=[list(r.bounds_hit) for r in res])
            seconds = {"uncertainty": time.perf_counter() - t}
            for i, j in zip(rows, judged):
                out[i] = (j, seconds, seconds["uncertainty"] / rows.size)
        return out
