"""One report for a run: a comparison page across materials and a page per material.

``OUT/report/index.html`` holds a table of every material (sphere thumbnails, errors in each
metric, parameters, verdict where the run analysed, flags) that sorts on a click on its
header; ``OUT/report/NAME.html`` shows one material at a readable size: parameters with their
standard errors, directional albedo, flags, a live view of the fit (WebGL 2, with the measured
table's sphere at the nearest light drawn: brdfcl.report.view.webgl), lit spheres (measured |
fitted | difference), slices and the analysis figures where there are some.  Plain files that
work offline: no script or style from elsewhere.  `brdfcl fit-all` and `brdfcl analyze` both write it (through
brdfcl.report.writers.pages); the images come from brdfcl.report.view.images.  The two pages
share their table cells, number formats and file writing, and nothing else uses them.
"""
from __future__ import annotations

import html
import os
import statistics
from dataclasses import dataclass, field
from pathlib import Path

from brdfcl._words import count
from brdfcl.model.compose import Model, ModelError
from brdfcl.optim.forms import DROP_TIE, SCREEN
from brdfcl.optim.selection import PENALTY
from brdfcl.report.files import writing
from brdfcl.report.published import Published
from brdfcl.report.view.images import draw_images
from brdfcl.report.view.webgl import view_html

METRICS = ("rmse_log", "rmse_l2", "rmse_cbrt", "rel_rmse")    # first, in this order; then any other


def error_columns(entries) -> list[str]:
    """METRICS, then every other error the entries report (a metric registered in
    brdfcl.model.metrics.IMPLEMENTED_METRICS adds its ``rmse_<name>``), in the order first seen."""
    cols = list(METRICS)
    for e in entries:
        cols += [k for k in e.errors if k not in cols]
    return cols
STYLE = """body{font-family:sans-serif;margin:1em auto;max-width:1400px;color:#222}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px;text-align:right}
th{background:#f3f3f3;cursor:pointer;vertical-align:bottom}td.l,th.l{text-align:left}
th.sorted-up::after{content:" \\25B2"}th.sorted-down::after{content:" \\25BC"}
img.thumb{height:56px;display:block}
.figs img{display:block;width:100%;max-width:1400px;height:auto;margin:.4em 0 1.2em}
.figs img.sphere{height:260px;width:auto;max-width:100%;margin:0}figure{margin:0 0 1.2em}
figcaption{font-size:13px;color:#444;max-width:1000px}
.diffraction{background:#fde8d8}.none{background:#e3eefc}.flag{color:#a00}small{color:#666}"""
SORT_JS = """document.querySelectorAll('table.sortable').forEach(function(t){
 t.querySelectorAll('th').forEach(function(th,i){th.addEventListener('click',function(){
  var up=!th.classList.contains('sorted-up');
  t.querySelectorAll('th').forEach(function(h){h.classList.remove('sorted-up','sorted-down');});
  th.classList.add(up?'sorted-up':'sorted-down');
  var rows=Array.prototype.slice.call(t.tBodies[0].rows);
  rows.sort(function(a,b){var x=a.cells[i].dataset.v,y=b.cells[i].dataset.v;
   var nx=parseFloat(x),ny=parseFloat(y);var c=(isNaN(nx)||isNaN(ny))?String(x).localeCompare(y):nx-ny;
   return up?c:-c;});
  rows.forEach(function(r){t.tBodies[0].appendChild(r);});});});});"""


@dataclass
class Entry:
    """What the report shows of one material, from a fit result or an analysis."""

    name: str
    model: str
    params: dict                          # name -> fitted value
    errors: dict
    status: str
    table: str | None = None              # path of the measurement
    verdict: str | None = None
    figures: list = field(default_factory=list)   # analysis figure paths
    uncertainty: dict | None = None
    albedo: dict | None = None
    flags: list = field(default_factory=list)
    lambdas: tuple | None = None          # the channels' wavelengths (um); None: R, G, B
    form: str | None = None               # the reflection lobe's form, where chosen (brdfcl.optim.forms)
    form_errors: dict | None = None       # {form: {"rmse_log", "penalised"}} of every candidate
    dropped: dict | None = None           # a lobe left out after the choice ({"lobes", "rmse_log", "rmse_log_with"})
    tabulated: bool = True                # a table (spheres and slices from it), not scattered samples
    truth: dict | None = None             # a synthetic material's known truth (brdfcl.model.synth.truth_of)
    published: Published | None = None    # its best published fit (brdfcl.report.published)

    @classmethod
    def from_document(cls, doc, table=None, **kw):
        """From a NAME.json document (brdfcl.report.output.result_document)."""
        lambdas = doc.get("wavelengths_um")
        return cls(doc["material"], doc["model"], {k: v["value"] for k, v in doc["params"].items()},
                   doc["errors"], str(doc.get("message", doc["status"])), table,
                   uncertainty=doc.get("uncertainty"),
                   albedo=doc.get("albedo"), flags=list(doc.get("flags") or []),
                   lambdas=tuple(lambdas) if lambdas else None, form=doc.get("form"),
                   form_errors=doc.get("form_errors"), dropped=doc.get("dropped"), **kw)

    @classmethod
    def from_result(cls, res, table=None, **kw):
        """From a brdfcl.optim.fit.FitResult."""
        lambdas = getattr(res, "lambdas", None)
        return cls(res.name, res.model, dict(res.params), res.errors, res.message, table,
                   uncertainty=getattr(res, "uncertainty", None), albedo=getattr(res, "albedo", None),
                   flags=list(getattr(res, "flags", None) or []), lambdas=tuple(lambdas) if lambdas else None, **kw)

    def fitted_model(self) -> Model:
        """The fitted Model, at its channels' wavelengths."""
        return Model(self.model) if self.lambdas is None else Model(self.model, lambdas=self.lambdas)


def write_report(out, entries, read_cells, title="brdfcl fits", log=None, engine=None, beside=None) -> Path:
    """Write ``OUT/report/``: images per material (drawn again only when the fit or the table
    changed), one page per material and the comparison page.  ``read_cells(path, index)`` reads a
    measured table's BRDF (3, len(index)) at some cells; ``engine(spec)``, where given, is a
    compiled Engine of a model spec (else one is made here; without any device, the images use
    the float64 reference); ``beside``: the job's image workers (brdfcl.report.view.images.Beside)."""
    rep = Path(out) / "report"
    rep.mkdir(parents=True, exist_ok=True)
    by_name = {e.name: e for e in entries}
    written: set[str] = set()

    def page(name, images):
        _write(rep / f"{name}.html", material_page(by_name[name], images, rep))
        written.add(name)
        if log:
            log(f"report: {name}")
    images = draw_images(rep, entries, read_cells, engine, beside, on_images=page)   # pages as images come
    for e in entries:
        if e.name not in written:
            page(e.name, images.get(e.name, {}))
    _write(rep / "index.html", comparison_page(entries, title, rep))
    return rep / "index.html"


def _groups(params):
    """Parameter columns: per-channel parameters of one name grouped (``ct.rho`` for its r, g, b)."""
    groups = {}
    for k in params:
        base, _, ch = k.rpartition("_")
        key = base if base and (ch in ("r", "g", "b") or (ch.endswith("nm") and ch[0].isdigit())) else k
        groups.setdefault(key, []).append(k)
    return groups


def comparison_page(entries, title, rep) -> str:
    groups: dict[str, list[str]] = {}
    for e in entries:
        for g, ks in _groups(e.params).items():
            groups.setdefault(g, ks)
    analysed = any(e.verdict for e in entries)
    formed = any(e.form for e in entries)
    metrics = error_columns(entries)
    compared = any(e.published for e in entries)
    heads = ["", "material"] + (["verdict"] if analysed else []) + (["form"] if formed else []) + metrics \
        + (list(PUBLISHED_HEADS) if compared else []) + list(groups) + ["status", "flags"]
    h = [_head(title), f"<h1>{html.escape(title)}</h1>",
         f"<p>{count(len(entries), 'material')}. Click a column header to sort; a material's name opens its page "
         "(spheres, slices, parameters with standard errors). Thumbnails: measured | fitted under the "
         "key light. Per-channel parameters show r / g / b and sort by their mean.</p>"]
    if compared:
        h.append(_published_summary(entries))
    h.append("<table class='sortable'><thead><tr>")
    h += [f"<th class='{'l' if i < 3 else ''}'>{html.escape(c)}</th>" for i, c in enumerate(heads)]
    h.append("</tr></thead><tbody>")
    for e in entries:
        thumb = f"{e.name}/{e.name}-thumb.png"
        cells = [_td(f"<img class='thumb' src='{_q(thumb)}' alt='{html.escape(e.name)} sphere'>", "", "l")
                 if (rep / thumb).exists() else _td("", ""),
                 _td(f"<a href='{_q(e.name)}.html'>{html.escape(e.name)}</a>", e.name, "l")]
        if analysed:
            cells.append(_td(html.escape(e.verdict or ""), e.verdict or "", "l"))
        if formed:
            cells.append(_td(html.escape(e.form or ""), e.form or "", "l"))
        cells += [_num(e.errors.get(m)) for m in metrics]
        if compared:
            cells += _published_cells(e)
        for g in groups:
            vals = [e.params[k] for k in _groups(e.params).get(g, [])]
            text = " / ".join(f"{v:.3g}" for v in vals) if len(vals) <= 3 else \
                f"{min(vals):.3g} .. {max(vals):.3g} ({len(vals)} bands)"
            cells.append(_td(text, sum(vals) / len(vals) if vals else ""))
        short = e.status.split(" (")[0].split("; ")[0]
        status = f"<span title='{html.escape(e.status, quote=True)}'>{html.escape(short)}</span>"
        cells.append(_td(status, e.status, "l"))
        tip = html.escape("\n".join(e.flags), quote=True)
        cells.append(_td(f"<span class='flag' title='{tip}'>{len(e.flags)}</span>" if e.flags else "0", len(e.flags)))
        h.append(f"<tr class='{html.escape(e.verdict or '')}'>" + "".join(cells) + "</tr>")
    h += ["</tbody></table>", f"<script>{SORT_JS}</script>"]
    return "\n".join(h)


PUBLISHED_HEADS = ("best published fit", "rmse_log / published")


def _published_cells(e) -> list[str]:
    """The comparison page's cells of a material's best published fit: its name and brdfcl's
    rmse_log over the published one's (empty where the scores name no fit of the material)."""
    p = e.published
    if p is None:
        return [_td("", ""), _td("", "")]
    ratio = p.ratio(e.errors.get("rmse_log"))
    if ratio is None:
        return [_td(html.escape(p.fit), p.fit, "l"), _td("", "")]
    text = f"{ratio:.3f}"
    return [_td(html.escape(p.fit), p.fit, "l"), _td(f"<b>{text}</b>" if ratio > 1 else text, ratio)]


def _published_summary(entries) -> str:
    """One paragraph: against how many published fits, the median ratio, and where brdfcl's is worse."""
    ratios = {e.name: r for e in entries
              if e.published and (r := e.published.ratio(e.errors.get("rmse_log"))) is not None}
    worse = sorted(n for n, r in ratios.items() if r > 1)
    text = (f"<p>Against the best published fit of each material (the scores given with --published, "
            f"rmse_log on the same table): {count(len(ratios), 'material')} compared")
    if ratios:
        text += (f", median ratio {statistics.median(ratios.values()):.3f} (below 1: brdfcl's fit is closer); "
                 + (f"worse on {len(worse)} (in bold): {html.escape(', '.join(worse))}" if worse else "worse on none"))
    return text + ".</p>"


def _form_cells(v: dict) -> str:
    """A candidate form's error cells and the row's end: fitted on the full table, on the preview
    cells only (italics), or not fitted (why)."""
    if "not_fitted" in v:
        return f"<td colspan='2'><i>not fitted: {html.escape(v['not_fitted'])}</i></td></tr>"
    err = _num(v.get("rmse_log")) if "rmse_log" in v else _td(f"<i>{v['rmse_preview']:.4g}</i>", v["rmse_preview"])
    return f"{err}{_num(v.get('penalised'))}</tr>"


def material_page(e, images, rep) -> str:
    h = [_head(e.name), "<p><a href='index.html'>&larr; all materials</a></p>",
         f"<h1>{html.escape(e.name)}</h1>",
         f"<p>model <code>{html.escape(e.model)}</code>; status {html.escape(e.status)}"
         + (f"; verdict <b>{html.escape(e.verdict)}</b>" if e.verdict else "") + "</p>",
         "<table><tr>" + "".join(f"<th>{m}</th>" for m in error_columns([e])) + "</tr><tr>"
         + "".join(_num(e.errors.get(m)) for m in error_columns([e])) + "</tr></table>"]
    if e.form_errors:
        h.append(f"<p>reflection lobe form <b>{html.escape(str(e.form))}</b>, the least penalised error "
                 f"(rmse_log x (1 + {PENALTY:g} x free parameters)) of the candidates; a form more than "
                 f"{SCREEN:.0%} behind the best on the preview cells (every n-th cell) was not fitted on the "
                 "full table, its error there is shown in italics:</p><table><tr><th>form</th>"
                 "<th>rmse_log</th><th>penalised</th></tr>"
                 + "".join(f"<tr><td>{html.escape(k)}</td>" + _form_cells(v)
                           for k, v in sorted(e.form_errors.items(),
                                              key=lambda kv: kv[1].get("penalised", float("inf"))))
                 + "</table>")
    if e.dropped:
        d = e.dropped
        without, with_it = (d.get(k, float("nan")) for k in ("rmse_log", "rmse_log_with"))
        h.append(f"<p>Left out after the choice: the {html.escape(', '.join(d.get('lobes', [])))} lobe, whose "
                 f"amplitude traded places with the diffuse's; rmse_log {without:.4g} without it against "
                 f"{with_it:.4g} with it (left out where at most {DROP_TIE:.1%} worse without it: the data do "
                 "not tell the two apart, and the diffuse alone is the simpler account).</p>")
    if e.published is not None:
        ratio = e.published.ratio(e.errors.get("rmse_log"))
        h.append(f"<p>Best published fit of this material (the scores given with --published): "
                 f"<b>{html.escape(e.published.fit)}</b>, rmse_log {e.published.rmse_log:.4g}"
                 + (f"; this fit's is {ratio:.3f} times that ({'closer' if ratio < 1 else 'not closer'})"
                    if ratio is not None else "") + ".</p>")
    if e.flags:
        h.append("<h2>Flags</h2><ul>" + "".join(f"<li class='flag'>{html.escape(f)}</li>" for f in e.flags) + "</ul>")
    h.append("<h2>Parameters</h2>" + _param_table(e))
    if e.albedo:
        h.append("<h2>Directional albedo of the fit</h2>" + _albedo_table(e.albedo, e.fitted_model().channels))
    h.append(view_html(e, images, rep))
    slices = ("Slices: BRDF x cos against the outgoing angle, and the lobes" if e.table is None or e.tabulated
              else "Measured samples and the fit in the plane of incidence")
    for key, head in (("spheres", "Lit spheres: measured | fitted | difference"), ("slices", slices)):
        if images.get(key):
            h.append(f"<h2>{head}</h2><div class='figs'>")
            for p in images[key]:
                img = f"<img class='{key[:-1]}' src='{_q(os.path.relpath(p, rep))}' alt='{html.escape(p.name)}'>"
                caption = images.get("captions", {}).get(p.name)
                h.append(f"<figure>{img}<figcaption>{html.escape(caption)}</figcaption></figure>" if caption else img)
            h.append("</div>")
    if images.get("exr"):
        h.append("<p><small>Linear images: " + ", ".join(
            f"<a href='{_q(os.path.relpath(p, rep))}'>{html.escape(p.name)}</a>" for p in images["exr"])
                 + "</small></p>")
    if e.figures:
        h.append("<h2>Analysis</h2><div class='figs'>")
        h += [f"<img src='{_q(os.path.relpath(p, rep))}' alt='{html.escape(Path(p).name)}'>" for p in e.figures]
        h.append("</div>")
    return "\n".join(h)


def true_values(model: Model, truth: dict) -> dict:
    """{fitted parameter: true value} of a synthetic material: the truth's value of a parameter of
    the same name, 0 for the amplitude of a lobe the truth's model lacks; the other parameters
    (a form the truth does not have) are left out."""
    params = truth.get("params", {})
    try:
        lobes = {lb.prefix for lb in Model(truth["model"]).lobes}
    except ModelError:              # a model this brdfcl does not know: the names alone
        lobes = {k.split(".")[0] for k in params}
    out = {}
    for s in model.slots:
        if s.name in params and isinstance(params[s.name], (int, float)):
            out[s.name] = float(params[s.name])
        elif s.amplitude and s.lobe not in lobes:
            out[s.name] = 0.0
    return out


def _param_table(e):
    se = (e.uncertainty or {}).get("std_error") or {}
    model = e.fitted_model()
    truth = true_values(model, e.truth) if e.truth else None
    head = "<th>true value</th><th>fitted / true - 1</th>" if truth is not None else ""
    rows = []
    if truth is not None:
        rows.append(f"<p>A synthetic material: its true model is <code>{html.escape(e.truth['model'])}</code> "
                    f"({html.escape(Path(e.truth['file']).name)} beside the table"
                    + (f", noise {e.truth['noise']:g}" if isinstance(e.truth.get("noise"), (int, float)) else "")
                    + "). A lobe the truth lacks is 0 there; a parameter of a form the truth does not have "
                    "has no true value.</p>")
    rows.append("<table><tr><th class='l'>parameter</th><th>value</th><th>standard error</th>"
                f"{head}<th class='l'>unit</th><th>bounds</th></tr>")
    for s in model.slots:
        v = e.params.get(s.name)
        err = se.get(s.name)
        cells = ""
        if truth is not None:
            t = truth.get(s.name)
            rel = (v / t - 1) if t not in (None, 0) and v is not None else None
            cells = _num(t) + ("<td></td>" if rel is None else f"<td>{rel:+.2%}</td>")
        rows.append(f"<tr><td class='l'>{html.escape(s.name)}</td>{_num(v)}"
                    f"<td>{'' if err is None else f'{err:.3g}'}</td>{cells}"
                    f"<td class='l'>{html.escape(s.param.unit or '')}</td>"
                    f"<td>{s.param.lo:.3g} .. {s.param.hi:.3g}</td></tr>")
    rows.append("</table>")
    if e.uncertainty and e.uncertainty.get("method"):
        rows.append(f"<p><small>{html.escape(e.uncertainty['method'])}</small></p>")
    return "".join(rows)


def _albedo_table(albedo, channels=("r", "g", "b")):
    angles, vals = albedo.get("theta_i_deg", []), albedo.get("channels", [])
    rows = ["<table><tr><th class='l'>theta_i (deg)</th>" + "".join(f"<th>{a:g}</th>" for a in angles) + "</tr>"]
    for c, name in enumerate(n.upper() if len(n) == 1 else n for n in channels):
        rows.append(f"<tr><td class='l'>{name}</td>" + "".join(
            f"<td class='{'flag' if v[c] > 1 else ''}'>{v[c]:.3f}</td>" for v in vals) + "</tr>")
    return "".join(rows) + "</table>"


def _head(title):
    return (f"<!doctype html><html lang='en'><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<link rel='icon' href='data:,'><style>{STYLE}</style>")


def _td(content, sort_value, cls=""):
    return f"<td class='{cls}' data-v='{html.escape(str(sort_value), quote=True)}'>{content}</td>"


def _num(v):
    return _td("" if v is None else f"{v:.4g}", "" if v is None else v)


def _q(path):
    from urllib.parse import quote
    return quote(str(path).replace(os.sep, "/"))


def _write(path, text):
    """Atomically, and not at all when the page is unchanged (a resumed run touches nothing)."""
    text += "\n"
    try:
        if path.read_text() == text:
            return
    except OSError:
        pass
    with writing(path):
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        tmp.write_text(text)
        os.replace(tmp, path)
