"""Analysis outputs: analysis.csv, OpenEXR maps, PNG figures and one index.html."""
from __future__ import annotations

import csv
import html
import io
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .geometry import bin_centres
from .output import atomic_write_text


def prepare(out):
    """Create ``out`` and ``out/figures``: a one-line OSError naming the folder if either cannot be
    written (brdfcl.run.check_output_dir); temporaries of a run killed mid-write are removed."""
    from .output import remove_stale_temporaries
    from .run import check_output_dir
    for d in (check_output_dir(out), check_output_dir(Path(out) / "figures")):
        remove_stale_temporaries(d)


@contextmanager
def writing(path):
    """A failed write of ``path`` as one line naming it (OpenEXR reports I/O errors as RuntimeError)."""
    try:
        yield
    except (OSError, RuntimeError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        why = (why.strip().splitlines() or [type(e).__name__])[0]
        raise OSError(f"{path}: cannot write: {why}") from e


def write_exr(path, channels: dict):
    """float32 channels (90, 90) into one OpenEXR file (rows theta_h, columns theta_d)."""
    import OpenEXR
    data = {k: np.ascontiguousarray(np.nan_to_num(v, nan=-1.0), dtype=np.float32) for k, v in channels.items()}
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    tmp = str(path) + ".tmp.exr"
    with writing(path):
        with OpenEXR.File(hdr, data) as f:
            f.write(tmp)
        Path(tmp).replace(path)


def _extent():
    th, td, _ = bin_centres()
    return np.degrees(td), np.degrees(th)


def _save(fig, path):
    tmp = str(path) + ".tmp.png"
    with writing(path):
        fig.savefig(tmp, dpi=90)
        Path(tmp).replace(path)


def figure_gradient(a, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x, y = _extent()
    fig, axes = plt.subplots(1, 3, figsize=(12, 4), constrained_layout=True)
    for c, ax in enumerate(axes):
        img = np.where(a.gradient.significant[c], a.gradient.angle_f[c], np.nan)
        im = ax.pcolormesh(x, y, img, cmap="coolwarm", vmin=0, vmax=90, shading="auto")
        ax.contour(x, y, a.gradient.region.astype(float), levels=[0.5], colors="k", linewidths=0.8)
        ax.set_facecolor("0.85")
        ax.set_title(f"{'RGB'[c]}: angle(grad p, grad f), score {a.gradient.score[c]:.2f}")
        ax.set_xlabel("theta_d (deg)")
        ax.set_ylabel("theta_h (deg)")
    fig.colorbar(im, ax=axes, label="degrees (0: level lines of f, diffraction)")
    fig.suptitle(f"{a.name}: gradient test at phi_d ~ 90 deg (grey: below noise; outline: decidable region)")
    _save(fig, path)
    plt.close(fig)


def figure_wavelength(a, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    w = a.wavelength
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    mid = np.sqrt(w.edges[1:] * w.edges[:-1])
    colors = ("tab:red", "tab:green", "tab:blue")
    f, q = w.points
    for c in range(3):
        axes[0].loglog(f[c][q[c] > 0], q[c][q[c] > 0], ".", ms=1, alpha=0.15, color=colors[c])
        axes[0].loglog(mid, w.curves[c] * np.nanmedian(q[c][q[c] > 0]) / np.nanmedian(w.curves[c]),
                       "-", color=colors[c], lw=2)
        axes[1].loglog(mid * 0.526, w.curves_f0[c], "-", color=colors[c], lw=2)
    axes[0].set_xlabel("f_c = 2 sin th cos td / lambda_c (1/um)")
    axes[0].set_ylabel("p - rho_d/pi (1/sr)")
    axes[0].set_title(f"data against f_c: scaled-curve spread {w.spread:.3f}")
    axes[1].set_xlabel("2 sin th cos td (no wavelength)")
    axes[1].set_title(f"scaled curves against f0: spread {w.spread_f0:.3f} (ratio {w.ratio:.2f})")
    fig.suptitle(f"{a.name}: wavelength check (curves collapse against f_c if diffraction is real)")
    _save(fig, path)
    plt.close(fig)


def figure_components(a, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.colors as mc
    import matplotlib.pyplot as plt
    x, y = _extent()
    keys = [("measured", "measured"), ("diffuse_diffraction", "diffuse + diffraction"),
            ("ct", "Cook-Torrance"), ("full", "full model")]
    inner = (x <= 75)[None, :]                       # colour range from outside the grazing spike
    vals = np.concatenate([a.slices[k][1][inner & np.isfinite(a.slices[k][1]) & (a.slices[k][1] > 0)]
                           for k, _ in keys])
    vmin, vmax = (np.percentile(vals, 1), np.percentile(vals, 99.9)) if vals.size else (1e-3, 1)
    fig, axes = plt.subplots(1, 4, figsize=(15, 4), constrained_layout=True)
    for ax, (k, title) in zip(axes, keys):
        img = np.where(a.slices[k][1] > 0, a.slices[k][1], np.nan)
        im = ax.pcolormesh(x, y, img, norm=mc.LogNorm(vmin=max(vmin, 1e-6), vmax=vmax), shading="auto")
        ax.set_title(title)
        ax.set_xlabel("theta_d (deg)")
    axes[0].set_ylabel("theta_h (deg)")
    fig.colorbar(im, ax=axes, label="BRDF, green channel (1/sr)")
    fig.suptitle(f"{a.name}: separate components of {a.specs['full']} at phi_d ~ 90 deg")
    _save(fig, path)
    plt.close(fig)


def write_material(out, a, figures=True):
    out = Path(out)
    ch = {}
    for c, n in enumerate("RGB"):
        ch[f"angle_f.{n}"] = np.where(a.gradient.significant[c], a.gradient.angle_f[c], np.nan)
        ch[f"consistent.{n}"] = a.gradient.consistent[c].astype(np.float32)
        for k in ("measured", "diffuse_diffraction", "ct", "full"):
            ch[f"{k}.{n}"] = a.slices[k][c]
    write_exr(out / f"{a.name}.exr", ch)
    if figures:
        figure_gradient(a, out / "figures" / f"{a.name}_gradient.png")
        figure_wavelength(a, out / "figures" / f"{a.name}_wavelength.png")
        figure_components(a, out / "figures" / f"{a.name}_components.png")


def write_index(out, analyses):
    out = Path(out)
    rows = [a.row() for a in analyses]
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    with writing(out / "analysis.csv"):
        atomic_write_text(out / "analysis.csv", buf.getvalue())
    cols = ["material", "verdict", "selected_lobes", "grad_score_g", "grad_cells", "grad_band_deg_g",
            "wavelength_ratio", "rmse_log_full", "rmse_log_no_diffraction", "rmse_log_no_ct",
            "peak_share_diffraction", "rmse_log_full_free", "peak_share_free"]
    h = ["<!doctype html><meta charset='utf-8'><title>brdfcl analysis</title>",
         "<style>body{font-family:sans-serif;margin:1em}td,th{border:1px solid #ccc;padding:2px 5px;"
         "font-size:12px}table{border-collapse:collapse}.diffraction{background:#fde8d8}"
         ".none{background:#e3eefc}.figs img{width:32%;vertical-align:top}h2{margin-bottom:0.2em}</style>",
         "<h1>Diffraction in measured BRDFs: per-material verdicts</h1>",
         "<p>Gradient test: share of the decidable wide-angle cells whose data gradient at phi_d ~ 90 deg "
         "is closer to the diffraction prediction (parallel to grad f) than to the Cook-Torrance one "
         "(theta_h = const tilted by 1/(cos ti cos to) and the Fresnel slope of the ridge). "
         "Wavelength check: spread of the channels against f_c over their spread without the wavelength (&lt; 1 collapses; &ge; 1.5 contradicts). Lobe "
         "comparison: penalised rmse_log with and without each lobe. Peak share: part of the fitted "
         "value at the specular peak carried by the diffraction lobe; the fits keep it at most equal to "
         "Cook-Torrance's (the talk's model), and the *_free columns show the full fit without that "
         "constraint.</p><table><tr>"]
    h += [f"<th>{html.escape(c)}</th>" for c in cols] + ["</tr>"]
    for a, r in zip(analyses, rows):
        cells = [f"<a href='#{html.escape(a.name)}'>{html.escape(a.name)}</a>"]
        cells += [html.escape(str(r[c])) for c in cols[1:]]
        h.append(f"<tr class='{r['verdict']}'>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    h.append("</table>")
    for a, r in zip(analyses, rows):
        h.append(f"<h2 id='{html.escape(a.name)}'>{html.escape(a.name)}: {r['verdict']}</h2>"
                 f"<p>lobes kept: {html.escape(r['selected_lobes'])}; final model: "
                 f"{html.escape(r['final_model'])}</p><div class='figs'>")
        h += [f"<a href='figures/{a.name}_{k}.png'><img src='figures/{a.name}_{k}.png' alt='{k}'></a>"
              for k in ("gradient", "wavelength", "components")]
        h.append("</div>")
    with writing(out / "index.html"):
        atomic_write_text(out / "index.html", "\n".join(h))
