"""The term registry as a table for people: `brdfcl terms` and docs/terms.md are made from it.

Every registered term (D, G, F, PSD) with its parameters (bounds, default, unit, log space,
per channel), what it is and the paper it comes from, read from the `Term` and `Param`
descriptions themselves, so the documentation cannot drift from the code.
"""
from __future__ import annotations

from brdfcl.model.compose import SHADOWINGS
from brdfcl.model.lobes import CookTorrance, Diffraction, Diffuse
from brdfcl.model.terms import REGISTRY, Param, Term

KINDS = {"ndf": "Normal distributions D (a Cook-Torrance lobe is named by its D)",
         "shadowing": "Shadowing and masking G (`smith` picks the one defined for the D)",
         "fresnel": "Fresnel F",
         "psd": "Surface power spectra S(f) (diffraction lobe)"}
HEADER = ("<!-- Made by `brdfcl terms` from the term registry; "
          "tests/test_catalogue.py checks it is current. -->")


def _param(p: Param) -> str:
    where = f"{p.lo:g}..{p.hi:g}, default {p.default:g}"
    flags = ", ".join(f for f, on in (("log space", p.log), ("per channel", p.per_channel)) if on)
    unit = f" {p.unit}" if p.unit else ""
    return f"`{p.name}`{unit} ({where}{', ' + flags if flags else ''})"


def _row(t: Term) -> str:
    params = "; ".join(_param(p) for p in t.params) or "none"
    if t.uses:
        params += f"; uses the D's `{'`, `'.join(t.uses)}`"
    only = f" (for {', '.join(t.ndfs)})" if t.ndfs else ""
    cells = [f"`{t.name}`", t.doc.replace("|", "\\|") + only, params, t.cite.replace("|", "\\|") or "-",
             f"`{source_file(t)}`"]
    return "| " + " | ".join(cells) + " |"


def source_file(t: Term) -> str:
    """The file that writes a term's formula, relative to the repository (``brdfcl/model/terms/ndf/ggx.py``)."""
    return t.origin.replace(".", "/") + ".py"


def terms_markdown() -> str:
    """Every registered term, grouped by kind, as Markdown."""
    out = [HEADER, "", "# Terms", "",
           "Every term a model can use, as registered in `brdfcl/model/terms/`: each file writes "
           "one formula, from which its derivatives, its float64 reference and its OpenCL "
           "function are generated.", ""]
    for kind, title in KINDS.items():
        out += [f"## {title}", "", "| name | what | parameters | source | formula |", "|---|---|---|---|---|"]
        out += [_row(t) for t in REGISTRY[kind].values()]
        out.append("")
    return "\n".join(out)


def _names(kind: str, default: str | None = None) -> str:
    return ", ".join(f"`{n}`" + (" (default)" if n == default else "") for n in REGISTRY[kind])


def _params(params) -> str:
    out = []
    for p in params:
        unit = f" ({p.unit})" if p.unit else ""
        out.append(f"`{p.name}_{{r,g,b}}`{unit}" if p.per_channel else f"`{p.name}`{unit}")
    return ", ".join(out)


def _per_term(kind: str) -> str:
    return "; ".join(f"{n}: {_params(t.params)}" for n, t in REGISTRY[kind].items() if t.params)


def lobes_markdown() -> str:
    """The lobes a model string may hold, with their options and parameters (the README's model
    table), from the lobe classes and the term registry."""
    ct, dr = CookTorrance(), Diffraction()
    rows = [
        ("`diffuse`", "", _params([Diffuse.amplitude])),
        ("`diffraction`", f"PSD {_names('psd', dr.psd.name)}; Fresnel {_names('fresnel', dr.fresnel.name)}",
         f"{_params([Diffraction.amplitude])}, the PSD's ({_per_term('psd')}), the Fresnel's"),
        (", ".join(f"`{n}`" for n in REGISTRY["ndf"]) + " (Cook-Torrance)",
         f"G {', '.join(f'`{a}`' for a in SHADOWINGS)} (default `smith` where the D has one, else "
         f"`vcavity`); Fresnel {_names('fresnel', ct.fresnel.name)}",
         f"{_params([CookTorrance.amplitude])}, the D's ({_per_term('ndf')}), "
         f"the Fresnel's ({_per_term('fresnel')})"),
    ]
    lines = [LOBES_BEGIN, "| lobe | options | parameters |", "| --- | --- | --- |"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines + [LOBES_END])


LOBES_BEGIN = "<!-- lobes: made by brdfcl.model.catalogue.lobes_markdown; tests/test_catalogue.py checks it -->"
LOBES_END = "<!-- end of lobes -->"
