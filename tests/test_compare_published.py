"""bench/compare_published.py's scoring as its callers use it (bench_fit.py --published and
bench_forms.py): fits labelled freely, each material's own model and values, scored beside the
published fits on the same cells."""
import csv
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import compare_published as cp  # noqa: E402

from brdfcl.data.merl import read_merl  # noqa: E402
from brdfcl.model.compose import Model  # noqa: E402


@pytest.mark.slow
def test_score_takes_a_model_per_material_and_scores_the_published_fits(demo_db):
    table = dataclasses.replace(read_merl(demo_db / "synth-smooth-metal.binary"), name="alum-bronze")
    ggx, gtr = Model("diffuse+diffraction+ggx"), Model("diffuse+diffraction+gtr:smith:dielectric")
    fits = {"default": {"alum-bronze": (gtr.spec, gtr.defaults())},
            "ggx": {"alum-bronze": (ggx.spec, ggx.defaults())}}
    row = cp.score([table], ["default", "ggx"], fits)["alum-bronze"]
    assert set(row) == {"default", "ggx", *cp.PUBLISHED}          # alum-bronze has every published fit
    assert len(cp.PUBLISHED) == 14
    assert all(np.isfinite(v) and v > 0 for v in row.values())
    assert row["default"] != row["ggx"]                            # each label evaluated in its own model


def _run(tmp_path, scores):
    run = {"specs": ["default", "ggx"], "seconds": {"default": 2.0, "ggx": 1.0}, "scores": scores,
           "data": "test", "models": {}, "cpu": "cpu", "date": "today", "version": "0"}
    (tmp_path / "published.json").write_text(json.dumps(run))
    return cp.report(tmp_path)


def test_report_names_the_best_of_all_published_fits(tmp_path):
    """The report ranks brdfcl against the best published fit of each material among those it has (Ngan
    et al.'s lack some materials), names it in the csv and the markdown, and keeps the SGD / ABC-mf
    comparison."""
    full = {k: 0.05 for k in cp.PUBLISHED}
    scores = {
        "alum-bronze": {"default": 0.01, "ggx": 0.03, **full, "he_ngan2005": 0.02, "sgd_bagher2012": 0.04},
        "white-marble": {"default": 0.02, "ggx": 0.01,       # not in Ngan et al.'s set
                         **{k: v for k, v in full.items() if not k.endswith("_ngan2005")},
                         "cooktorrance_low2012_e1": 0.016},
    }
    text = _run(tmp_path, scores)
    rows = {r["material"]: r for r in csv.DictReader(open(tmp_path / "published.csv"))}
    assert rows["alum-bronze"]["best_published"] == "he_ngan2005"
    assert float(rows["alum-bronze"]["ratio_default_to_best"]) == pytest.approx(0.5)
    assert float(rows["alum-bronze"]["ratio_default_to_sgd_abc"]) == pytest.approx(0.25)
    assert rows["white-marble"]["best_published"] == "cooktorrance_low2012_e1"
    assert rows["white-marble"]["he_ngan2005"] == "nan"
    assert float(rows["white-marble"]["ratio_ggx_to_best"]) == pytest.approx(0.625)
    assert "Against the better of the SGD and ABC microfacet fits" in text
    assert "Against the best of all 14 published fits" in text
    assert "The best published fit, materials: CT-Low-E1 1, He-Ngan 1." in text
    line = next(x for x in text.splitlines() if x.startswith("| alum-bronze |"))
    assert "| He-Ngan | 0.0200 |" in line and line.endswith("| 0.250 | 0.750 | 0.500 | 1.500 |")
    # the summaries: default 2 x better than He-Ngan on alum-bronze (0.5), worse than CT-Low-E1 on white-marble
    assert "white-marble (1.25)" in text


def test_report_of_an_older_run_with_three_published_fits(tmp_path):
    three = ("sgd_bagher2012", "abc_low2012_microfacet_e2", "abc_low2012_smooth_e2")
    text = _run(tmp_path, {"alum-bronze": {"default": 0.01, "ggx": 0.02, **dict(zip(three, (0.04, 0.03, 0.02)))}})
    with open(tmp_path / "published.csv") as fh:
        header = next(csv.reader(fh))
    assert header[:6] == ["material", "default", "ggx", *three]
    assert "best of all 3 published fits" in text and "ABC-sm 1" in text
