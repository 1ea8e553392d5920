"""What the command line prints to a user: one-line usage errors with a "did you mean", and help
text that says what the commands do (checked against what they do)."""
from __future__ import annotations

import subprocess
import sys

import pytest

from brdfcl.app import cli


def usage_error(capsys, *argv) -> str:
    """The one line a usage error prints (exit status 2, nothing on stdout, no usage block), found
    by the parser (SystemExit) or by the command (main's return value)."""
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    assert code == 2
    out, err = capsys.readouterr()
    assert out == "" and "usage:" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize("argv, line", [
    ((), "brdfcl: error: give a command: info, synth, fit-all, calibrate, analyze, export, terms or params "
         "(see brdfcl --help)"),
    (("fit-all", "--demo"), "brdfcl fit-all: error: the following arguments are required: --out "
                            "(see brdfcl fit-all --help)"),
    (("fit-all", "--demo", "--out", "o", "--metric", "l3"),
     "brdfcl fit-all: error: argument --metric: invalid choice 'l3'; choose from l2, log, cbrt "
     "(see brdfcl fit-all --help)"),
    (("fit-all", "--demo", "--out", "o", "--batch", "abc"),
     "brdfcl fit-all: error: argument --batch: invalid int value: 'abc' (see brdfcl fit-all --help)"),
    (("synth", "a", "b"), "brdfcl synth: error: unrecognized arguments: b (see brdfcl synth --help)"),
    (("--bogus",), "brdfcl: error: unrecognized argument --bogus (see brdfcl --help)"),
    (("xyz",), "brdfcl: error: invalid choice 'xyz'; the commands are info, synth, fit-all, calibrate, analyze, "
               "export, terms, params (see brdfcl --help)"),
])
def test_usage_errors_are_one_line(capsys, argv, line):
    assert usage_error(capsys, *argv) == line


@pytest.mark.parametrize("argv, line", [
    (("fit-al",), "brdfcl: error: invalid choice 'fit-al' (did you mean fit-all?)"),
    (("anlyze", "--demo"), "brdfcl: error: invalid choice 'anlyze' (did you mean analyze?)"),
    # the unknown option is what matters, not the --out it leaves missing
    (("fit-all", "--demo", "--ouut", "o"), "brdfcl fit-all: error: unrecognized argument --ouut (did you mean --out?)"),
    (("fit-all", "--demo", "--out", "o", "--qiet"),
     "brdfcl fit-all: error: unrecognized argument --qiet (did you mean --quiet?)"),
    (("analyze", "--demo", "--out", "o", "--no-figurs", "--no-reprt"),
     "brdfcl analyze: error: unrecognized arguments --no-figurs (did you mean --no-figures?), "
     "--no-reprt (did you mean --no-report?)"),
    (("fit-all", "--demo", "--out", "o", "--metric", "lg"),
     "brdfcl fit-all: error: argument --metric: invalid choice 'lg' (did you mean log?)"),
])
def test_did_you_mean(capsys, argv, line):
    assert usage_error(capsys, *argv) == line


def test_prefixes_and_negative_numbers_are_not_unknown():
    args = cli.build_parser().parse_args(["fit-all", "--demo", "--ou", "o", "--seed", "-1", "--cutof", "70"])
    assert (args.out, args.seed, args.cutoff) == ("o", -1, 70.0)


def test_help_keeps_its_usage_block(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["fit-all", "--help"])
    assert e.value.code == 0 and capsys.readouterr().out.startswith("usage: brdfcl fit-all ")


def test_database_or_demo(capsys, tmp_path):
    from brdfcl.data.readers import formats_text
    assert usage_error(capsys, "fit-all", "--out", tmp_path / "o") == (
        f"brdfcl fit-all: error: give a database folder (of {formats_text('or')}) or --demo "
        "(see brdfcl fit-all --help)")
    assert "MERL .binary tables" in formats_text() and "Cornell .brdf samples" in formats_text()
    assert usage_error(capsys, "analyze", tmp_path, "--demo", "--out", tmp_path / "o") == (
        f"brdfcl analyze: error: a database folder ({tmp_path}) and --demo: give one of them "
        "(see brdfcl analyze --help)")
    assert usage_error(capsys, "fit-all", tmp_path / "nope", "--out", tmp_path / "o") == (
        f"brdfcl fit-all: error: {tmp_path / 'nope'}: no such folder or file (see brdfcl fit-all --help)")


def test_unknown_demo_material(capsys, tmp_path):
    line = usage_error(capsys, "synth", tmp_path, "--materials", "synth-fabrc")
    assert line.startswith("brdfcl synth: error: unknown demo material synth-fabrc; valid: synth-")
    assert line.endswith(" (did you mean synth-fabric?)")


# ---- help text --------------------------------------------------------------------------------

COMMANDS = ("info", "synth", "fit-all", "calibrate", "analyze", "export", "terms", "params")


def help_of(capsys, *argv) -> str:
    with pytest.raises(SystemExit) as e:
        cli.main([*argv, "--help"])
    assert e.value.code == 0
    return capsys.readouterr().out


def test_top_help_is_for_users(capsys):
    text = help_of(capsys)
    flat = " ".join(text.split())
    assert "brdfcl fits analytic BRDF models" in flat
    for developer_words in ("cmd_", "``", "build_parser", "brdfcl.app", "FitOptions", "One function per command"):
        assert developer_words not in text, developer_words
    assert "\n  brdfcl fit-all merl/ --out out/merl " in text         # an example, kept as written
    for cmd in COMMANDS:
        assert f"\n    {cmd} " in text or f"\n    {cmd}\n" in text, cmd


@pytest.mark.parametrize("cmd", COMMANDS)
def test_every_command_has_a_description_and_an_example(capsys, cmd):
    text = help_of(capsys, cmd)
    usage, description = text.split("\n\n")[:2]
    assert usage.startswith(f"usage: brdfcl {cmd} ")
    assert not description.startswith(("positional", "options")) and len(description.split()) > 10, description
    assert "\nexample" in text and f"\n  brdfcl {cmd}" in text.split("\nexample")[1]
    assert "-\n" not in text                                            # no word split at a hyphen


def test_fit_all_help_names_every_format_it_reads(capsys):
    from brdfcl.data.readers import READERS
    text = " ".join(help_of(capsys, "fit-all").split())
    description = text.split(" positional arguments:")[0]
    for suffix in (".binary", *READERS):
        assert suffix in description, suffix
    assert "MERL .binary" in description and "Cornell .brdf" in description


def test_fit_all_help_says_what_it_fits_without_model(capsys):
    """The default the help states is what a run without --model chooses among (brdfcl.optim.forms)."""
    from brdfcl.optim.fit import FitOptions
    from brdfcl.optim.forms import DEFAULT_FORMS, form_keys, resolve
    parse = cli.build_parser().parse_args
    text = " ".join(help_of(capsys, "fit-all").split())
    args = parse(["fit-all", "--demo", "--out", "o"])
    chosen = resolve(cli._forms(args), cli.fit_options(args), model_given="model" in vars(args))
    assert chosen == DEFAULT_FORMS
    keys = ", ".join(form_keys(FitOptions().model, chosen))
    assert f"without --model: diffuse + diffraction + a reflection lobe whose form is chosen per material " \
           f"among {keys}" in text
    assert f"reflection lobe in each of the forms {keys} (NDF[:shadowing]:Fresnel)" in text
    assert f"(default {FitOptions().model}" not in text.split("--metric")[0]     # not a model of its own
    # only a model asked for is fitted as given
    args = parse(["fit-all", "--demo", "--out", "o", "--model", FitOptions().model])
    assert resolve(cli._forms(args), cli.fit_options(args), model_given=True) is None


# ---- a mistyped model -------------------------------------------------------------------------

@pytest.mark.parametrize("spec, says", [
    ("difraction+ggx", "unknown lobe 'difraction'; did you mean 'diffraction'? lobes: "),
    ("DIFRACTION+ggx", "unknown lobe 'difraction'; did you mean 'diffraction'? lobes: "),
    ("difraction:hp+ggx", "unknown lobe 'difraction' in 'difraction:hp'; did you mean 'diffraction'? lobes: "),
    ("diffuse+gxx", "unknown lobe 'gxx'; did you mean 'ggx'? lobes: "),
    ("diffraction:hpp+ggx", "'diffraction:hpp': bad option 'hpp'; did you mean 'hp'? lobes: "),
    ("ggx:smth", "'ggx:smth': bad option 'smth'; did you mean 'smith'? lobes: "),
    ("diffuse+ggx:smith:schlik", "'ggx:smith:schlik': bad option 'schlik'; did you mean 'schlick'? lobes: "),
    ("diffraction:hp:abc", "'diffraction:hp:abc': two PSDs; give one; lobes: "),
    ("ggx:schlick:dielectric", "'ggx:schlick:dielectric': two Fresnel terms; give one; lobes: "),
    ("diffuse+phong", "unknown lobe 'phong'; lobes: "),
])
def test_a_mistyped_model_gets_the_nearest_name(spec, says):
    from brdfcl.model.compose import Model, ModelError
    with pytest.raises(ModelError) as e:
        Model(spec)
    assert str(e.value).startswith(says), str(e.value)


def test_a_mistyped_fixed_parameter_gets_the_nearest_name():
    from brdfcl.model.compose import Model, ModelError
    with pytest.raises(ModelError, match=r"^cannot fix 'ct.alhpa': not a parameter of diffuse\+ggx:smith:schlick; "
                                         r"did you mean 'ct.alpha'\? parameters: diffuse.rho_r, "):
        Model("diffuse+ggx", fixed={"ct.alhpa": 0.1})


def test_fit_all_says_the_model_typo_once(capsys, tmp_path):
    assert cli.main(["fit-all", "--demo", "--out", str(tmp_path / "o"), "--model", "difraction+ggx"]) == 2
    out, err = capsys.readouterr()
    assert err.startswith("brdfcl: error: unknown lobe 'difraction'; did you mean 'diffraction'? lobes: diffuse, ")
    assert err.count("difraction") == 1 and len(err.splitlines()) == 1 and not (tmp_path / "o").exists()


def test_no_far_fetched_parameter_is_suggested():
    """ct.F0_r in a model with a dielectric Fresnel (ct.eta) is no typo of ct.rho_r."""
    from brdfcl.model.compose import Model, ModelError
    with pytest.raises(ModelError) as e:
        Model("diffuse+gtr:smith:dielectric", fixed={"ct.F0_r": 0.5})
    assert "did you mean" not in str(e.value)


# ---- plurals ----------------------------------------------------------------------------------

def test_counted_nouns():
    from brdfcl._words import count, noun
    assert [count(n, "material") for n in (0, 1, 2)] == ["0 materials", "1 material", "2 materials"]
    assert count(1, "sample set") == "1 sample set" and noun(3, "entry", "entries") == "entries"


def test_synth_of_one_material_says_one(capsys, tmp_path):
    assert cli.main(["synth", str(tmp_path), "--materials", "synth-fabric"]) == 0
    assert f"wrote 1 material and truth.json to {tmp_path}\n" in capsys.readouterr().out


def test_a_single_file_of_no_known_format_is_refused_before_any_work(tmp_path):
    from brdfcl.data.readers import READERS
    notes = tmp_path / "notes.txt"
    notes.write_text("x")
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(notes), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [
        f"brdfcl: error: {notes}: unknown format: brdfcl reads {', '.join(sorted(READERS))} files"]
    assert not (tmp_path / "o").exists()


def test_a_mistyped_form_gets_the_nearest():
    from brdfcl.model.compose import ModelError
    from brdfcl.optim.forms import parse_forms
    with pytest.raises(ModelError, match=r"unknown NDF gtx \(did you mean gtr\?\)"):
        parse_forms("gtx:dielectric")
