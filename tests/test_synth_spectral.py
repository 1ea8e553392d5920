"""Synthetic spectral materials scattered like a real measurement (brdfcl synth --like): the
writers round trip, the files hold the model's reference at the file's directions, the CLI."""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdfcl.data.cornell import read_cornell, write_cornell
from brdfcl.data.csvsamples import read_csv, write_csv
from brdfcl.data.errors import DataError
from brdfcl.data.inputs import InputOverwriteError
from brdfcl.data.samples import Channel, make_samples, rgb_channels
from brdfcl.model.compose import Model
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.synth import SPECTRAL, Ramp, spectral_values, write_spectral_synth

# -n with --dist loadgroup (the slow tier in .ci/run): one process runs this module's tests, not
# one after another, so its costly fixture is session-scoped: made once there
pytestmark = pytest.mark.xdist_group("test_synth_spectral")

# odd wavelengths and angles: what a repr round trip must keep to the last bit
LAMBDAS_UM = (0.4, 0.4123456789, 0.55, 0.61, 0.7000000001, 0.78)


def _samples(n=200, seed=3, channels=None):
    rng = np.random.default_rng(seed)
    channels = channels or [Channel(f"{x * 1000:g}nm", x) for x in LAMBDAS_UM]
    ti, to = rng.uniform(0, 0.5 * np.pi, n), rng.uniform(0, 0.5 * np.pi, n)
    ti[0], to[1] = 0.0, 0.5 * np.pi                     # both ends of the range
    pi, po = rng.uniform(-np.pi, np.pi, n), rng.uniform(-2 * np.pi, 2 * np.pi, n)
    v = np.exp(rng.normal(-3, 2, (n, len(channels))))
    v[2, 0] = 0.0
    return make_samples(None, ti, pi, to, po, v, channels, name="round trip")


def _same(a, b, values=True):
    """The same angles, wavelengths and (unless not asked) values, to the last bit."""
    for f in ("theta_i", "phi_i", "theta_o", "phi_o") + (("values",) if values else ()):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    np.testing.assert_array_equal(a.wavelengths, b.wavelengths)


def test_cornell_round_trip(tmp_path):
    s = _samples()
    path = tmp_path / "s.brdf"
    write_cornell(s, path)
    text = path.read_text()
    assert text.startswith("# written by brdfcl") and "write_cornell" in text.splitlines()[0]
    back = read_cornell(path)
    _same(s, back)
    assert back.name == "s" and [c.name for c in back.channels][2] == "550nm"
    write_cornell(back, tmp_path / "again.brdf")            # a file read back writes the same numbers
    assert (tmp_path / "again.brdf").read_text().split("\n", 1)[1] == text.split("\n", 1)[1]


def test_csv_round_trip(tmp_path):
    s = _samples()
    write_csv(s, tmp_path / "s.csv", radians=True)
    _same(s, read_csv(tmp_path / "s.csv"))


def test_cornell_refuses_what_it_cannot_hold(tmp_path):
    rgb = _samples(channels=list(rgb_channels()))
    with pytest.raises(ValueError, match="not a spectral band") as e:
        write_cornell(rgb, tmp_path / "rgb.brdf")
    assert "\n" not in str(e.value)
    far = _samples(channels=[Channel("x", 5e-5)])
    with pytest.raises(ValueError, match="out of the range"):
        write_cornell(far, tmp_path / "far.brdf")
    s = _samples()
    missing = type(s)(s.name, None, s.theta_i, s.phi_i, s.theta_o, s.phi_o, np.where(s.values > 1, np.nan, s.values),
                      s.channels, s.weights)
    with pytest.raises(ValueError, match="NaN"):
        write_cornell(missing, tmp_path / "nan.brdf")


def test_parameters_by_band():
    model = Model("diffuse+diffraction:hp+ggx", lambdas=(0.4, 0.55, 0.7, 0.8))
    v = model.as_dict(spectral_values(model, {"diffuse.rho": Ramp(0.3, 0.6), "diffraction.rho": 0.01,
                                              "ct.alpha": 0.05}))
    assert [v[f"diffuse.rho_{c}"] for c in model.channels] == pytest.approx([0.3, 0.45, 0.6, 0.7])
    assert {v[f"diffraction.rho_{c}"] for c in model.channels} == {0.01}
    assert v["ct.alpha"] == 0.05
    with pytest.raises(ValueError, match="not a parameter"):
        spectral_values(model, {"ct.eta": 1.5})


@pytest.fixture(scope="session")
def written(tmp_path_factory, krylon):
    out = tmp_path_factory.mktemp("spectral")
    truth = write_spectral_synth(out, krylon.path, log=None)
    return out, truth


def test_files_hold_the_reference_at_the_measured_directions(written, krylon):
    out, truth = written
    assert set(truth) == set(SPECTRAL)
    doc = json.loads((out / "truth.json").read_text())
    assert Path(doc["like"]).resolve() == Path(krylon.path).resolve() and doc["noise"] == 0.0 and doc["seed"] == 0
    assert doc["wavelengths_nm"] == [400.0 + 10 * k for k in range(31)]
    assert sorted(p.name for p in out.iterdir()) == ["brdf", "csv", "truth.json"]     # a folder per format
    assert sorted(p.name for p in (out / "brdf").iterdir()) == sorted(f"{n}.brdf" for n in SPECTRAL)
    assert sorted(p.name for p in (out / "csv").iterdir()) == sorted(f"{n}.csv" for n in SPECTRAL)
    for name, t in doc["materials"].items():
        brdf, csv = read_cornell(out / "brdf" / f"{name}.brdf"), read_csv(out / "csv" / f"{name}.csv")
        _same(brdf, csv)                                   # both formats: the same samples
        _same(brdf, krylon, values=False)                  # at the measurement's directions and bands
        assert not np.array_equal(brdf.values, krylon.values)
        model = Model(t["model"], lambdas=tuple(brdf.wavelengths))
        v = np.array([t["params"][n] for n in model.names])
        expect = model.reference(Cells.from_directions(brdf.wi, brdf.wo), v, jacobian=False).T
        np.testing.assert_allclose(brdf.values, expect, rtol=1e-14, atol=0)
    p = doc["materials"]["synth-spectral-diffraction"]["params"]
    amps = [p[k] for k in p if k.startswith("diffraction.rho_")]
    assert len(amps) == 31 and len(set(amps)) == 1            # the lambda^-4 law holds exactly
    assert p["diffraction.a"] == 2.0 and p["ct.alpha"] == 0.05
    assert not any(k.startswith("diffraction") for k in doc["materials"]["synth-spectral-plastic"]["params"])


def test_noise_is_seeded_and_multiplicative(written, krylon, tmp_path):
    clean, _ = written
    name = "synth-spectral-plastic"
    a, b = tmp_path / "a", tmp_path / "b"
    write_spectral_synth(a, krylon.path, [name], noise=0.05, seed=7, formats="csv", log=None)
    write_spectral_synth(b, krylon.path, [name], noise=0.05, seed=7, formats=["csv"], log=None)
    assert sorted(p.name for p in a.iterdir()) == [f"{name}.csv", "truth.json"]
    va, vb = read_csv(a / f"{name}.csv").values, read_csv(b / f"{name}.csv").values
    np.testing.assert_array_equal(va, vb)
    r = np.log(va / read_cornell(clean / "brdf" / f"{name}.brdf").values)
    assert abs(r.mean()) < 0.005 and 0.045 < r.std() < 0.055
    assert json.loads((a / "truth.json").read_text())["noise"] == 0.05


def test_refuses_the_input_folder_and_rgb(tmp_path, krylon):
    inp = tmp_path / "in"
    inp.mkdir()
    like = inp / "krylon_blue.brdf"
    shutil.copy(krylon.path, like)
    with pytest.raises(InputOverwriteError):
        write_spectral_synth(inp, like, log=None)
    assert [p.name for p in inp.iterdir()] == ["krylon_blue.brdf"]
    rgb = tmp_path / "rgb.csv"
    write_csv(_samples(channels=list(rgb_channels())), rgb)
    with pytest.raises(DataError, match="not spectral bands") as e:
        write_spectral_synth(tmp_path / "out", rgb, log=None)
    assert str(rgb) in str(e.value) and not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="unknown format"):
        write_spectral_synth(tmp_path / "out", like, formats=("brdf", "exr"), log=None)


def run(*args):
    return subprocess.run([sys.executable, "-m", "brdfcl.app.cli", *args], capture_output=True, text=True)


@pytest.mark.slow
def test_cli(tmp_path, krylon):
    out = tmp_path / "out"
    r = run("synth", "--like", krylon.path, "--out", str(out), "--formats", "brdf",
            "--materials", "synth-spectral-diffraction")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["synth-spectral-diffraction.brdf", "truth.json"]
    _same(read_cornell(out / "synth-spectral-diffraction.brdf"), krylon, values=False)

    bad = tmp_path / "bad.brdf"
    bad.write_text("31\n400 410\n")
    for like in (bad, tmp_path / "absent.csv"):
        r = run("synth", "--like", str(like), "--out", str(tmp_path / "never"))
        assert r.returncode != 0
        assert r.stderr.count("\n") == 1 and str(like) in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "never").exists()
    r = run("synth", "--like", krylon.path, "--out", str(tmp_path / "never"), "--materials", "synth-mirror")
    assert r.returncode == 2 and "unknown spectral material" in r.stderr and "synth-spectral-plastic" in r.stderr
