"""Every registered writer (brdfcl.report.writers.IMPLEMENTED_WRITERS), found in the registry (no
hand-written list): a newly registered output is tested by registering it.  On a fit job and an
analysis job with every output asked for, built from stand-in results (no fitting), each writer
must write into the output folder only, leave no temporary file, and write the same bytes twice."""
import os
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from brdfcl.analysis.analyze import analyze_material, lobe_images
from brdfcl.analysis.gradient import phi90_slice
from brdfcl.app.run import fit_all
from brdfcl.data.merl import read_merl
from brdfcl.device.engine import Engine
from brdfcl.model.compose import Model
from brdfcl.model.synth import DEMO, demo_values
from brdfcl.optim.selection import variants
from brdfcl.report.writers import ANALYSIS, FIT, IMPLEMENTED_WRITERS, ExportWriter, Item, Job, Writer, export_writers

NAME = "synth-smooth-metal"
WRITERS = list(IMPLEMENTED_WRITERS)


def stand_in(spec, params=None):
    """A FitResult as the writers read it, at the demo material's own parameters."""
    m = Model(spec)
    values = demo_values(m, params or {})
    errors = {"rmse_log": 0.01, "rmse_l2": 0.02, "rmse_cbrt": 0.03, "rel_rmse": 0.04}
    return SimpleNamespace(name=NAME, model=m.spec, metric="log", params=m.as_dict(values), success=True,
                           status=1, message="converged (stand-in)", loss=1e-4, errors=errors, seconds=1.0, nfev=10,
                           history=[(1.0, "local", 0.01)], bounds_hit=[], stages={"total": 1.0},
                           uncertainty=None, albedo=None, flags=[])


@pytest.fixture(scope="module")
def material(demo_db):
    spec, params = DEMO[NAME]
    table = str(demo_db / f"{NAME}.binary")
    specs = variants(Model(spec).spec)
    fits = {k: stand_in(s, {p: v for p, v in params.items() if p in Model(s).names or
                            f"{p}_r" in Model(s).names}) for k, s in specs.items()}
    brdf = read_merl(table).brdf()
    a = analyze_material(NAME, brdf, fits, specs)
    a.slices = {"measured": phi90_slice(brdf)[0], **lobe_images(specs["full"], a.fits["full"].params)}
    return SimpleNamespace(table=table, fit=fits["full"], analysis=a, engines={})


def jobs(material, out):
    """A fit job and an analysis job into ``out`` with every output asked for, and their item."""
    def engine(spec):
        if spec not in material.engines:
            material.engines[spec] = Engine(Model(spec))
        return material.engines[spec]
    tables = {NAME: material.table}
    fit = Job(FIT, out, options={"model": material.fit.model}, exports=frozenset(export_writers()), pages=True,
              tables=tables, engine=engine)
    analysis = Job(ANALYSIS, out, figures=True, pages=True, tables=tables)
    return [(fit, Item.of_fit(fit, material.fit)), (analysis, Item(NAME, material.table, analysis=material.analysis))]


def run_writer(writer, material, out):
    """Run one writer through its steps on every job it applies to; the files it left, with their bytes."""
    out.mkdir()
    ran = False
    for job, item in jobs(material, out):
        if not writer.applies_to(job):
            continue
        ran = True
        writer.prepare(job)
        job.items.append(item)
        writer.write(job, item)
        writer.finish(job, job.items)
    assert ran, f"writer {writer.name} applies to no job"
    return {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def test_the_registry():
    assert WRITERS and len(set(WRITERS)) == len(WRITERS)
    for name, w in IMPLEMENTED_WRITERS.items():
        assert isinstance(w, Writer) and w.name == name, name
        assert sys.modules[type(w).__module__].__doc__, f"writer {name}: its module says what it writes"
    assert set(export_writers()) >= {"merl", "brdf_explorer"}
    assert all(isinstance(w, ExportWriter) for w in export_writers().values())
    with pytest.raises(ValueError, match="job kind"):
        Job("render", Path("."))


@pytest.mark.slow
@pytest.mark.parametrize("name", WRITERS)
def test_every_writer_writes_its_files_into_the_output_only(name, material, tmp_path):
    writer = IMPLEMENTED_WRITERS[name]
    first = run_writer(writer, material, tmp_path / "a")
    assert first, f"writer {name} wrote nothing"
    assert sorted(os.listdir(tmp_path)) == ["a"]                        # nothing beside the output
    assert not [p for p in first if ".tmp" in p.name], first            # no temporary left
    again = run_writer(writer, material, tmp_path / "b")
    assert again.keys() == first.keys()
    assert [p for p in first if first[p] != again[p]] == []             # deterministic


def test_fit_all_exports_what_is_asked(demo_db, tmp_path):
    path = demo_db / "synth-mirror.binary"
    out = tmp_path / "out"
    rep = fit_all([path], out, model="diffuse+ggx", export=("merl", "brdf_explorer"))
    assert rep.ok and rep.outputs["summary"] == out / "summary.csv" and rep.pages is None
    assert (out / "synth-mirror.binary").stat().st_size > 0
    assert "::begin shader" in (out / "synth-mirror.brdf").read_text()
    (out / "synth-mirror.brdf").unlink()
    rep = fit_all([path], out, model="diffuse+ggx", export="brdf_explorer")     # resumed, export written
    assert rep.resumed == ["synth-mirror"] and not rep.results and (out / "synth-mirror.brdf").is_file()
    with pytest.raises(ValueError, match="unknown export png; valid: merl, brdf_explorer"):
        fit_all([path], out, model="diffuse+ggx", export=["png"])


def test_summary_reads_each_result_once_and_again_when_it_changes(tmp_path, monkeypatch):
    """summary.csv is rewritten after every fit from the folder's NAME.json files: with the writer's
    cache an unchanged file is not parsed again (80 fits read 3240 files before), a replaced one
    (new inode, as every result is written) is, and the summary shows its new content."""
    import json

    from brdfcl.report.output import read_results
    from brdfcl.report.writers.summary import write_summary

    def doc(name, rmse):
        return {"material": name, "model": "diffuse", "metric": "log", "seconds": 1.0, "evaluations": 3,
                "errors": {"rmse_log": rmse, "rmse_l2": 0.0, "rmse_cbrt": 0.0, "rel_rmse": 0.0},
                "status": "ok", "params": {"diffuse.rho_r": {"value": 0.5}}}

    def put(name, rmse):
        tmp = tmp_path / f"{name}.tmp"
        tmp.write_text(json.dumps(doc(name, rmse)))
        os.replace(tmp, tmp_path / f"{name}.json")
    parsed = []
    real_loads = json.loads
    monkeypatch.setattr(json, "loads", lambda s: parsed.append(1) or real_loads(s))
    cache: dict = {}
    put("a", 0.25)
    put("b", 0.5)
    write_summary(tmp_path, cache)
    assert len(parsed) == 2
    write_summary(tmp_path, cache)
    assert len(parsed) == 2                                    # nothing read again
    put("b", 0.125)                                            # same size, new inode
    put("c", 0.75)
    text = write_summary(tmp_path, cache).read_text()
    assert len(parsed) == 4                                    # b again, c new
    assert ",0.125," in text and ",0.5," not in text and text.count("\n") == 4
    assert read_results(tmp_path) == read_results(tmp_path, cache)
