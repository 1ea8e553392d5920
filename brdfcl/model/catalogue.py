"""The term registry as a table for people: `brdfcl terms` and docs/terms.md are made from it.

Every registered term (D, G, F, PSD) with its parameters (bounds, default, unit, log space,
per channel), what it is and the paper it comes from, read from the `Term` and `Param`
descriptions themselves, so the documentation cannot drift from the code.
"""
from __future__ import annotations

from brdfcl.model.terms import REGISTRY, Param, Term

KINDS = {"ndf": "Normal distributions D (Cook-Torrance lobes: `ggx`, `beckmann`, `sgd`, `epd`)",
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
