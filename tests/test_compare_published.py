"""bench/compare_published.py's scoring as its callers use it (bench_fit.py --published and
bench_forms.py): fits labelled freely, each material's own model and values, scored beside the
published fits on the same cells."""
import dataclasses
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
    assert all(np.isfinite(v) and v > 0 for v in row.values())
    assert row["default"] != row["ggx"]                            # each label evaluated in its own model
