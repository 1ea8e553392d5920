"""The CLI holds no fit default of its own: a flag the user does not give leaves FitOptions' (and
LMOptions') default in place, --help shows those defaults, and changing one in the options classes
changes the CLI with no edit in cli.py.  Other defaults come from the function a command runs."""
from __future__ import annotations

import inspect
from dataclasses import dataclass, field, fields

import pytest

import brdfcl.optim.fit
from brdfcl.app import cli
from brdfcl.app.analyze import analyze
from brdfcl.app.run import fit_all
from brdfcl.model.synth import write_synth
from brdfcl.optim.fit import FitOptions
from brdfcl.optim.lm import LMOptions


def parse(*argv):
    return cli.build_parser().parse_args(list(argv))


def help_text(capsys, *argv):
    """The --help of a command, with its line wrapping undone."""
    with pytest.raises(SystemExit) as e:
        cli.main([*argv, "--help"])
    assert e.value.code == 0
    return " ".join(capsys.readouterr().out.split())


def default(func, name):
    return inspect.signature(func).parameters[name].default


def assert_same_fields(got, want):
    """Field by field, so a failure names the field whose default the CLI changed."""
    assert type(got) is type(want)
    for f in fields(want):
        assert getattr(got, f.name) == getattr(want, f.name), f.name


@pytest.mark.parametrize("cmd, job", [("fit-all", fit_all), ("analyze", analyze)])
def test_no_flag_changes_no_default(cmd, job):
    assert_same_fields(cli.fit_options(parse(cmd, "--demo", "--out", "o")), FitOptions())
    args = parse(cmd, "db", "--out", "o", "--model", "diffuse+ggx")
    assert_same_fields(cli.fit_options(args), FitOptions(model="diffuse+ggx"))
    assert args.batch == default(job, "batch")


def test_every_fit_flag_sets_its_field():
    args = parse("fit-all", "db", "--out", "o", "--model", "diffuse+ggx", "--metric", "l2", "--no-cos",
                 "--cutoff", "60", "--double", "--device", "0", "--vector-width", "4", "--global", "none",
                 "--candidates", "10", "--starts", "2", "--max-iter", "5", "--fix", "ct.alpha=0.2",
                 "--ct-peak", "--seed", "3")
    want = FitOptions(model="diffuse+ggx", metric="l2", cosw=False, cutoff_deg=60.0, real="double",
                      device="0", vector_width=4, global_method="none", n_candidates=10, n_starts=2,
                      lm=LMOptions(max_iter=5), fixed={"ct.alpha": 0.2}, ct_peak=True, seed=3)
    assert_same_fields(cli.fit_options(args), want)
    assert cli.fit_options(parse("analyze", "db", "--out", "o", "--cutoff", "90")).cutoff_deg is None


def test_help_shows_the_defaults_of_the_classes(capsys):
    d = FitOptions()
    for cmd, job in (("fit-all", fit_all), ("analyze", analyze)):
        text = help_text(capsys, cmd)
        for shown in (f"fit metric (default {d.metric})",
                      f"default {d.cutoff_deg:g})", f"global search (default {d.global_method})",
                      f"Sobol candidates per material (lds; default {d.n_candidates})",
                      f"local searches per material (lds; default {d.n_starts})",
                      f"Levenberg-Marquardt iterations (default {d.lm.max_iter})",
                      f"seed of the global search (default {d.seed})",
                      f"default {default(job, 'batch')})"):
            assert shown in text, (cmd, shown)
    args = parse("synth", "out")
    assert (args.noise, args.missing, args.seed) == tuple(default(write_synth, k) for k in ("noise", "missing", "seed"))
    assert parse("params").model == d.model


@dataclass
class Changed(FitOptions):
    """Every default the CLI shows or converts, changed."""

    model: str = "diffuse+ggx"
    metric: str = "cbrt"
    cutoff_deg: float | None = None
    real: str = "double"
    global_method: str = "crs2"
    n_candidates: int = 17
    n_starts: int = 3
    lm: LMOptions = field(default_factory=lambda: LMOptions(max_iter=7, ftol=1e-5))
    seed: int = 11


def test_cli_follows_a_changed_default(monkeypatch, capsys):
    monkeypatch.setattr(brdfcl.optim.fit, "FitOptions", Changed)
    assert_same_fields(cli.fit_options(parse("fit-all", "--demo", "--out", "o")), Changed())
    # --max-iter changes only the iterations: the rest of the default LMOptions stays
    args = parse("analyze", "--demo", "--out", "o", "--max-iter", "9")
    assert_same_fields(cli.fit_options(args), Changed(lm=LMOptions(max_iter=9, ftol=1e-5)))
    assert "compared (default diffuse+ggx;" in help_text(capsys, "analyze")
    text = help_text(capsys, "fit-all")
    assert "without --model: diffuse + a reflection lobe whose form is chosen per material among" in text
    for shown in ("fit metric (default cbrt)", "none; default none)",
                  "float64 kernels and data (default float64)", "global search (default crs2)",
                  "(lds; default 17)", "(lds; default 3)", "iterations (default 7)", "search (default 11)"):
        assert shown in text, shown
    assert parse("params").model == "diffuse+ggx"
