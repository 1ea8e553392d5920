"""Time to write the report of a finished demo run, per material page: the images (drawn
afresh into a scratch report folder, in this process) and the pages' HTML alone; and, in
interleaved pairs, a material's images with and without the live view's measured turntable.

    python bench/bench_report_pages.py OUT [--repeat 5] [--pairs 6]

OUT is a finished `brdfcl fit-all --demo` output; the tables are the demo database's.  Prints
the time per page of each part (best of the repeats), a page's size and its images' size, then
the turntable's ratio pair by pair (the fits evaluated with the float64 reference, once).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def pages(entries, repeat):
    from brdfcl.report.view.images import draw_images
    from brdfcl.report.view.pages import material_page
    from brdfcl.report.writers.pages import _read_cells
    draw, html = [], []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            rep = Path(tmp) / "report"
            rep.mkdir()
            t = time.perf_counter()
            images = draw_images(rep, entries, _read_cells)
            draw.append((time.perf_counter() - t) / len(entries))
            t = time.perf_counter()
            for e in entries:
                material_page(e, images.get(e.name, {}), rep)
            html.append((time.perf_counter() - t) / len(entries))
            size = sum(len(material_page(e, images.get(e.name, {}), rep)) for e in entries) / len(entries)
            files = sum(p.stat().st_size for p in rep.rglob("*") if p.is_file()) / len(entries)
    print(f"{len(entries)} pages: images {min(draw):.3f} s a page, HTML {1000 * min(html):.2f} ms a page, "
          f"page {size / 1024:.1f} KiB, images {files / 1024:.0f} KiB a material")


def turntable_pairs(entries, pairs):
    from brdfcl.model.compose import Model
    from brdfcl.report.view.evaluate import Evaluator
    from brdfcl.report.view.images import PLAN
    from brdfcl.report.view.material import write_material
    from brdfcl.report.view.views import plan
    from brdfcl.report.writers.pages import _read_cells
    plans = {"without": plan(*PLAN[:3]), "with": plan(*PLAN)}
    fitted = {}
    for k, p in plans.items():
        for e in entries:
            model = Model(e.model)
            fitted[k, e.name] = model, Evaluator(p, model)([[e.params[n] for n in model.names]])[0]
    times: dict[str, list[float]] = {k: [] for k in plans}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(pairs):
            for k, p in plans.items():
                t = time.perf_counter()
                for e in entries:
                    model, f = fitted[k, e.name]
                    write_material(Path(tmp) / e.name, e.name, _read_cells(e.table, p.table_cells), model, f, p)
                times[k].append((time.perf_counter() - t) / len(entries))
    ratio = np.array(times["with"]) / np.array(times["without"])
    print(f"a material's images, without / with the turntable: {1000 * np.median(times['without']):.1f} / "
          f"{1000 * np.median(times['with']):.1f} ms (medians); ratio {np.median(ratio):.3f} "
          f"({ratio.min():.3f} .. {ratio.max():.3f}) over {pairs} interleaved pairs")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--pairs", type=int, default=6)
    args = ap.parse_args()
    from brdfcl.model.synth import demo_dir
    from brdfcl.report.output import read_results
    from brdfcl.report.view.pages import Entry

    db = demo_dir()
    entries = [Entry.from_document(d, str(db / f"{d['material']}.binary")) for d in read_results(args.out)]
    pages(entries, args.repeat)
    if args.pairs:
        turntable_pairs(entries, args.pairs)


if __name__ == "__main__":
    main()
