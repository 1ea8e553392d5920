"""ALTA's own two real measurements: the MERL pink-felt slice in COS_TH and the CEA gray-tape
retro-reflection data (``.dat``, ISOTROPIC_TL_TV_PROJ_DPHI, no #PARAM_OUT).

They are not in this repository (pink-felt is MERL-derived).  The tests read them from the folder
BRDFCL_ALTA_DATA, default ../shared/data/alta, and skip when they are absent; from a clone of
ALTA (https://github.com/belcour/alta)::

    mkdir -p DATA
    git -C alta show HEAD:data/brdf/pink-felt-1d.alta > DATA/pink-felt-1d.alta
    git -C alta show HEAD:documents/data/retro-gray-tape.dat > DATA/retro-gray-tape.dat
    BRDFCL_ALTA_DATA=DATA python -m pytest -q tests/test_alta_real.py
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdfcl.data.alta import read_rows
from brdfcl.data.readers import read_measurement
from brdfcl.report.sample_figures import in_plane, incidence_panels

ROOT = Path(__file__).resolve().parents[1]
ALTA_DATA = Path(os.environ.get("BRDFCL_ALTA_DATA", ROOT.parent / "shared" / "data" / "alta"))
FILES = {"pink-felt-1d": "pink-felt-1d.alta", "retro-gray-tape": "retro-gray-tape.dat"}


def alta_file(name: str) -> Path:
    path = ALTA_DATA / FILES[name]
    if not path.is_file():
        why = (f"ALTA's real data not available: {path} is missing (set BRDFCL_ALTA_DATA to a folder holding "
               f"{', '.join(FILES.values())}; tests/test_alta_real.py says how to get them)")
        pytest.skip(why)             # even under BRDFCL_REQUIRE_SHARED: they are not part of ../shared
    return path


def test_pink_felt_is_a_backscatter_slice():
    path = alta_file("pink-felt-1d")
    s = read_measurement(path)
    assert s.n_samples == 90 and [c.name for c in s.channels] == ["R", "G", "B"]
    np.testing.assert_allclose(s.wi, s.wo, atol=1e-12)                  # theta_d = 0: wi = wo = h
    np.testing.assert_allclose(np.cos(s.theta_i), read_rows(path).x[:, 0], atol=1e-12)
    assert 0.05 < np.median(s.values) < 0.2                              # felt: a diffuse 1/sr level


def test_retro_gray_tape_peaks_at_the_light():
    s = read_measurement(alta_file("retro-gray-tape"))
    assert s.n_samples == 7400 and len(s.channels) == 1                  # 5 views past the horizon left out
    light = np.round(np.degrees(s.theta_o), 6)
    assert sorted(set(light)) == [15.0, 30.0, 60.0]                     # the light, written second
    for deg in (15.0, 30.0):
        at = light == deg
        peak = np.argmax(s.values[at, 0])
        np.testing.assert_allclose(s.wi[at][peak], s.wo[at][peak], atol=1e-9)   # the retro direction
    mask, _ = in_plane(s)
    np.testing.assert_allclose(np.degrees(incidence_panels(s, mask)), [15.0, 30.0, 60.0], atol=0.01)


@pytest.mark.slow
def test_fit_all_reports_and_exports_both(tmp_path):
    """fit-all with its default options on a folder of the two, then an export of each fit."""
    db = tmp_path / "db"
    db.mkdir()
    for name in FILES:
        shutil.copy(alta_file(name), db / FILES[name])

    def cli(*args):
        r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return r
    cli("fit-all", db, "--out", tmp_path / "fits", "--quiet")
    for name in FILES:
        doc = json.loads((tmp_path / "fits" / f"{name}.json").read_text())
        assert np.isfinite(doc["errors"]["rmse_log"]) and doc["source"] == str(db / FILES[name])
        assert (tmp_path / "fits" / "report" / f"{name}.html").stat().st_size > 0
        assert (tmp_path / "fits" / "report" / name / f"{name}-in-plane-slices.png").stat().st_size > 10000
        cli("export", tmp_path / "fits" / f"{name}.json", "--alta", tmp_path / f"{name}-fit.alta")
        measured, fitted = read_rows(db / FILES[name]), read_rows(tmp_path / f"{name}-fit.alta")
        assert fitted.param_in == measured.param_in and np.array_equal(fitted.x, measured.x)
        assert fitted.values.shape == measured.values.shape and np.isfinite(fitted.values).mean() > 0.99
