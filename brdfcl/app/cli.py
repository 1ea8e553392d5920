"""The `brdfcl` command line.  Errors are one line naming the problem (tracebacks with --debug).

One function per command (``cmd_*``), the parser (``build_parser``) and ``main``; the flags that
make FitOptions, shared by fit-all and analyze, are brdfcl.app.arguments.  A command runs a job
(brdfcl.app.run.fit_all, brdfcl.app.analyze.analyze) or a writer (``export``) and prints its outcome.

What a user reads is written for users and kept apart from these notes: ``DESCRIPTION`` and
``EXAMPLES`` are `brdfcl --help`, each command's description and examples are in build_parser;
``Parser`` makes every usage error one line with a "did you mean", ``HelpFormatter`` keeps the
examples as written.
"""
from __future__ import annotations

import argparse
import difflib
import logging
import os
import re
import sys
import textwrap

from brdfcl._version import __version__
from brdfcl._words import count, noun
from brdfcl.app.arguments import UsageError, add_database_arguments, default_of, fit_options
from brdfcl.data.readers import formats_text

# fit_options and UsageError are this module's too (tests and scripts import them from here)
__all__ = ["UsageError", "build_parser", "fit_options", "main"]
MESSAGE_CHARS = 400                 # a longer error line is cut in its middle (--debug shows all)
NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+")     # a negative number is a value, not an option

# What `brdfcl --help` says (the developer notes are this module's docstring)
DESCRIPTION = f"""\
brdfcl fits analytic BRDF models (diffuse, diffraction and Cook-Torrance reflection lobes) to
measured BRDF databases with OpenCL, on the CPU by default or on any OpenCL device. It reads
{formats_text()}, writes each material's fit (NAME.json), a summary table and an HTML
report, and tests which materials show diffraction."""
EXAMPLES = """\
examples:
  brdfcl synth merl/                     write a synthetic database to try
  brdfcl fit-all merl/ --out out/merl    fit every material of merl/
  brdfcl fit-all --demo --out out/demo   fit the embedded demo database
  brdfcl analyze merl/ --out out/tests   which materials show diffraction
  brdfcl info                            the OpenCL devices brdfcl can use

`brdfcl COMMAND --help` describes a command and its options. An error is one line; --debug
shows its traceback."""


class HelpFormatter(argparse.HelpFormatter):
    """Wraps a description's or epilog's prose to the terminal, a paragraph at a time, and keeps
    an indented line (an example) as written; never breaks a line at a hyphen (fit-all,
    synth-fabric, --select-lobes stay whole)."""

    def _split_lines(self, text, width):
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)

    def _fill_text(self, text, width, indent):
        blocks = []
        for para in text.strip("\n").split("\n\n"):
            lines: list[str] = []
            prose: list[str] = []
            for line in [*para.splitlines(), None]:
                if (line is None or line.startswith("  ")) and prose:
                    lines.append(textwrap.fill(" ".join(prose), width, initial_indent=indent,
                                               subsequent_indent=indent, break_on_hyphens=False))
                    prose = []
                if line is not None:
                    (lines.append(indent + line) if line.startswith("  ") else prose.append(line.strip()))
            blocks.append("\n".join(lines))
        return "\n\n".join(blocks)


def default_fit_text(model: str, forms: str, short: bool = False) -> str:
    """What fit-all fits without --model (brdfcl.optim.forms.resolve): ``model``'s lobes, its
    reflection lobe in each of the candidate ``forms``, the best form kept per material."""
    from brdfcl.model.compose import Model
    from brdfcl.optim.forms import form_keys
    lobes = " + ".join([lb.spec().split(":")[0] for lb in Model(model).lobes if lb.role != "reflection"]
                       + ["a reflection lobe"])
    keys = ", ".join(form_keys(model, forms))
    if short:
        return f"{lobes} whose form is chosen per material among {keys}, see --forms"
    return (f"each material is fitted with {lobes} in each of the forms {keys} (NDF[:shadowing]:Fresnel), "
            "forms far behind on every 8th cell left out there, and the form of least penalised error is "
            "kept (see --forms)")


class Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one line, ``PROG: error: PROBLEM (see PROG --help)``, exit
    status 2 (the usage block only with --help), with a "did you mean" for a mistyped command,
    option or choice.  ``add_subparsers`` makes the subcommands' parsers of this class too.

    argparse reports the first problem it meets; an unknown option often causes the next (a
    mistyped --out leaves --out missing), so an unknown option among the arguments is reported
    before any other problem."""

    def parse_known_args(self, args=None, namespace=None):
        self._argv = list(sys.argv[1:] if args is None else args)      # for error(): what was given
        return super().parse_known_args(args, namespace)

    def parse_args(self, args=None, namespace=None):
        parsed, extra = self.parse_known_args(args, namespace)
        unknown = self._unknown(self._argv)
        if unknown:                                 # given before the command: this parser's own
            self.error(unknown)
        sub = self._command_parser(parsed)
        if extra:                                   # a subcommand's parser leaves them to this one
            (sub or self).error((sub or self)._unknown(extra) or f"unrecognized arguments: {' '.join(extra)}")
        if sub is None and self._commands() is not None:
            names = list(self._commands().choices)
            self.error(f"give a command: {', '.join(names[:-1])} or {names[-1]}")
        return parsed

    def error(self, message):
        unknown = self._unknown(getattr(self, "_argv", []))
        text = unknown or message
        hint = "" if "did you mean" in text else f" (see {self.prog} --help)"
        self.exit(2, f"{self.prog}: error: {text}{hint}\n")

    def _check_value(self, action, value):
        if action.choices is None or value in action.choices:
            return
        choices = [str(c) for c in action.choices]
        close = difflib.get_close_matches(str(value), choices, n=1)
        if isinstance(action, argparse._SubParsersAction):
            raise argparse.ArgumentError(None, f"invalid choice '{value}'" + (
                f" (did you mean {close[0]}?)" if close else f"; the commands are {', '.join(choices)}"))
        raise argparse.ArgumentError(action, f"invalid choice '{value}'" + (
            f" (did you mean {close[0]}?)" if close else f"; choose from {', '.join(choices)}"))

    def _commands(self):
        return next((a for a in self._actions if isinstance(a, argparse._SubParsersAction)), None)

    def _command_parser(self, parsed):
        commands = self._commands()
        name = getattr(parsed, commands.dest, None) if commands is not None else None
        return commands.choices[name] if name is not None else None

    def _unknown(self, tokens) -> str:
        """'unrecognized argument --ouut (did you mean --out?)' for the options among ``tokens``
        that this parser does not know (a unique prefix of one it knows is known, as argparse
        takes it), or ''.  A parser of commands reads only the tokens before the command."""
        bad = []
        for tok in tokens:
            if tok == "--":
                break
            if not tok.startswith("-") or tok == "-" or NUMBER.match(tok):
                if self._commands() is not None:
                    break
                continue
            flag = tok.split("=", 1)[0]
            if not any(s.startswith(flag) for s in self._option_string_actions):
                bad.append(flag)
        if not bad:
            return ""
        longs = [s for s in self._option_string_actions if s.startswith("--")]
        shown = []
        for flag in bad:
            close = difflib.get_close_matches(flag, longs, n=1)
            shown.append(f"{flag} (did you mean {close[0]}?)" if close else flag)
        return f"unrecognized argument{'s' * (len(bad) > 1)} {', '.join(shown)}"


def cmd_info(args):
    import pyopencl as cl

    from brdfcl.device import buildcheck, cpu, runtimes
    from brdfcl.device.platforms import DeviceError, all_devices, check, describe_device, has_fp64, pick_device, status
    from brdfcl.device.width import forced_width
    forced_width(args.vector_width)             # a bad BRDFCL_VECTOR_WIDTH: one line, exit 2
    print(f"brdfcl {__version__}, pyopencl {cl.VERSION_TEXT}, CPU: {cpu.name()}")
    devs = all_devices()
    quiet = logging.getLogger("brdfcl")
    level, _ = quiet.level, quiet.setLevel(logging.ERROR)   # what pick_device notes is listed below
    try:
        chosen, why_none = pick_device(args.device), ""
    except DeviceError as e:
        if args.device:                         # a device asked for by name: a usage error
            raise
        chosen, why_none = None, str(e)
    finally:
        quiet.setLevel(level)
    for i, (p, d) in enumerate(devs):
        for line in describe_device(i, p, d) + [f"     {status(i, devs, chosen)}"]:
            print(line)
        if check(i, devs).ok:
            for real in ("float", "double") if has_fp64(d) else ("float",):
                print(f"     {real}: {_program_check(i, real, args.vector_width)}", flush=True)
    for rt in runtimes.prepare():
        print(f"loaded by brdfcl: {rt.name} {rt.version} from {rt.library.parent} (pip's intel-opencl-rt)")
    if runtimes.not_loaded():
        print(f"not loaded: {runtimes.not_loaded()}")
    if chosen is None:
        print(f"no device: {why_none}")
        return 1
    p, d = chosen
    index = next(i for i, (q, e) in enumerate(devs) if (q.int_ptr, e.int_ptr) == (p.int_ptr, d.int_ptr))
    left = [buildcheck.label(q) for j, (q, _) in enumerate(devs) if not check(j, devs).ok]
    print(f"default device: [{index}] {d.name} on {buildcheck.label(p)}"
          + (f"; cannot build: {', '.join(left)}" if left else ""))
    return 0


def _program_check(index, real, vector_width):
    """The width used for the default model on a device, why, and its program's self-test."""
    from brdfcl.device.engine import Engine
    from brdfcl.device.program import ProgramError
    from brdfcl.model.compose import DEFAULT_MODEL
    try:
        eng = Engine(DEFAULT_MODEL, device=str(index), real=real, vector_width=vector_width)
    except (ProgramError, ValueError) as e:
        return f"no working program: {e.cause if isinstance(e, ProgramError) else e}"
    w = eng.width
    why = w.reason if w is not None else "not a CPU: one cell per work-item"
    return f"vector width {eng.opt.vw} ({why}); self-test {eng.self_test}"


def cmd_synth(args):
    from brdfcl.model.synth import DEMO, SPECTRAL, write_spectral_synth, write_synth
    if args.out and args.out_flag and args.out != args.out_flag:
        raise UsageError(f"two output folders, {args.out} and --out {args.out_flag}: give one")
    out = args.out_flag or args.out
    if not out:
        raise UsageError("give an output folder: brdfcl synth OUT, or --out OUT")
    known, what = (SPECTRAL, "spectral") if args.like else (DEMO, "demo")
    mats = [m.strip() for m in args.materials.split(",") if m.strip()] if args.materials else None
    if mats:
        bad = [m for m in mats if m not in known]
        if bad:
            close = difflib.get_close_matches(bad[0], known, n=1)
            raise UsageError(f"unknown {what} {noun(len(bad), 'material')} {', '.join(bad)}; valid: "
                             f"{', '.join(known)}" + (f" (did you mean {close[0]}?)" if close else ""))
    if not args.like:
        if args.formats is not None:
            raise UsageError("--formats applies to spectral materials (with --like FILE) only")
        write_synth(out, mats, noise=args.noise, missing=args.missing, seed=args.seed)
        print(f"wrote {count(len(mats or DEMO), 'material')} and truth.json to {out}")
        return 0
    if args.missing:
        raise UsageError("--missing applies to the MERL demo only (not with --like)")
    formats = (args.formats.split(",") if args.formats is not None
               else default_of(write_spectral_synth, "formats"))
    write_spectral_synth(out, args.like, mats, noise=args.noise, seed=args.seed, formats=formats)
    print(f"wrote {count(len(mats or SPECTRAL), 'spectral material')} at the directions and bands of {args.like} "
          f"and truth.json to {out}")
    return 0


def _database_job(args):
    """(source folder, FitOptions, log) shared by fit-all and analyze."""
    from brdfcl.model.synth import demo_dir
    if args.demo and args.database is not None:
        raise UsageError(f"a database folder ({args.database}) and --demo: give one of them")
    if not args.demo and args.database is None:
        raise UsageError(f"give a database folder (of {formats_text('or')}) or --demo")
    if args.database is not None and not os.path.exists(args.database):
        raise UsageError(f"{args.database}: no such folder or file")
    source = demo_dir() if args.demo else args.database
    from tqdm import tqdm
    # tqdm.write keeps stage messages from tearing the progress bar on a terminal
    log = (lambda s: None) if args.quiet else (lambda s: tqdm.write(s, file=sys.stderr))
    return source, fit_options(args), log


def _forms(args) -> str:
    """--forms as given; else the default choice, unless a model or a fixed parameter was asked for."""
    if args.forms is not None:
        return args.forms
    return "none" if "model" in vars(args) or "fix" in vars(args) else "default"


# how to go on when --out holds results made with other options (brdfcl.app.resume.ResultsDiffer)
RESUME_PROCEED = "to proceed, give another output folder (--out), or add --overwrite to refit and replace those results"


def cmd_fit_all(args):
    from brdfcl.app.resume import OPTION_FLAGS, ResultsDiffer
    from brdfcl.app.run import fit_all
    source, opts, log = _database_job(args)
    client = None
    if args.workers or args.scheduler:
        from brdfcl.app.cluster import make_client
        client = make_client(args.scheduler, args.workers)
    try:
        report = fit_all(source, args.out, opts, batch=args.batch, export=args.export_merl,
                         quiet=args.quiet, log=log, client=client, select_lobes=args.select_lobes,
                         free_peak=args.free_peak, overwrite=args.overwrite, pages=not args.no_report,
                         rgb=args.rgb, forms=_forms(args), published=args.published)
    except ResultsDiffer as e:          # in the command line's words, not the Python API's
        raise ValueError(e.message(OPTION_FLAGS, RESUME_PROCEED)) from e
    finally:
        if client is not None:
            client.close()
    n_ok = sum(r.success for r in report.results)
    failed = [r for r in report.results if not r.success]
    print(f"fitted {count(n_ok, 'material')} in {report.seconds:.1f} s ({len(report.resumed)} already done, "
          f"{len(failed)} failed, {len(report.skipped)} skipped); results in {args.out}/summary.csv"
          + (f", report {report.pages}" if report.pages else ""))
    for r in failed:
        print(f"failed: {r.name}: {r.message}", file=sys.stderr)
    for why in report.skipped.values() if args.quiet else ():     # else logged as they happened
        print(f"skipped: {why}", file=sys.stderr)
    return 0 if report.ok else 1


def cmd_analyze(args):
    from brdfcl.app.analyze import analyze
    source, opts, log = _database_job(args)

    def on_skip(path, why):                 # as fit-all: one line per file, also with --quiet
        print(f"skipped: {why if path in why else f'{path}: {why}'}", file=sys.stderr, flush=True)
    res = analyze(source, args.out, opts, batch=args.batch, log=log, figures=not args.no_figures,
                  ct_peak=not args.free_peak, on_skip=on_skip, pages=not args.no_report)
    n = sum(a.verdict == "diffraction" for a in res)
    print(f"analysed {count(len(res), 'material')}: {n} with diffraction, {len(res) - n} without, "
          f"{len(res.skipped)} skipped; see {args.out}/analysis.csv and {args.out}/index.html"
          + ("" if args.no_report else f", report {args.out}/report/index.html"))
    return 0 if res.ok else 1


def cmd_export(args):
    """A finished fit (NAME.json) as a BRDF Explorer file, a MERL table and/or an ALTA data file,
    without refitting: the export writers of a fit job (brdfcl.report.writers), each to the path
    given."""
    from pathlib import Path

    from brdfcl.report.export.fitfile import load_fit
    from brdfcl.report.writers import FIT, Job, export_writers
    wanted = {"brdf_explorer": args.brdf_explorer, "merl": args.merl, "mitsuba": args.mitsuba, "alta": args.alta}
    if args.at is not None and not args.alta:
        raise UsageError("--at FILE gives the points of --alta PATH: give --alta too")
    if not any(wanted.values()):
        raise UsageError("give one or more of --brdf-explorer PATH, --merl PATH, --mitsuba DIR, --alta PATH")
    writers = export_writers()
    if args.at is not None:
        from brdfcl.report.writers.alta import AltaExport
        writers["alta"] = AltaExport(at=args.at)
    for out in wanted.values():
        if out and os.path.exists(out) and os.path.samefile(out, args.fit):
            raise UsageError(f"{out}: would overwrite the fit it exports")
    fit = load_fit(args.fit)

    def engine(spec):
        # local: only a MERL export needs OpenCL
        from brdfcl.device.engine import Engine
        return Engine(fit.model, device=args.device)
    job = Job(FIT, Path(args.fit).parent, exports=frozenset(k for k, v in wanted.items() if v), engine=engine,
              log=print)
    for name, path in wanted.items():
        if path:
            print(f"wrote {writers[name].export(Path(path), fit.doc, job)}")
    return 0


def cmd_terms(args):
    """Every registered term as Markdown (docs/terms.md is this output)."""
    from brdfcl.model.catalogue import terms_markdown
    print(terms_markdown())
    return 0


def cmd_params(args):
    from brdfcl.model.compose import Model
    m = Model(args.model)
    print(f"model {m.spec}: {m.n_params} parameters")
    print("lobes: " + ", ".join(f"{lb.prefix}.* = {lb.spec()} ({lb.role})" for lb in m.lobes)
          + "; a kind's second lobe is prefixed ct2 (diffuse2, diffraction2), its third ct3, ...")
    print(f"{'name':24s} {'lo':>9s} {'hi':>9s} {'default':>9s} {'search':>17s} {'space':>5s}  unit  meaning")
    for s in m.slots:
        p = s.param
        lo, hi = p.search_range
        print(f"{s.name:24s} {p.lo:9.3g} {p.hi:9.3g} {p.default:9.3g} {f'{lo:.3g}..{hi:.3g}':>17s} "
              f"{'log' if p.log else 'lin':>5s}  {p.unit or '-':5s} {p.doc}")
    return 0


def build_parser():
    from brdfcl.app import calibrate
    from brdfcl.app.analyze import analyze
    from brdfcl.app.run import fit_all
    from brdfcl.model.synth import DEMO, SPECTRAL, write_spectral_synth, write_synth
    from brdfcl.optim.fit import FitOptions
    from brdfcl.optim.forms import DEFAULT_FORMS
    ap = Parser(prog="brdfcl", formatter_class=HelpFormatter, description=DESCRIPTION, epilog=EXAMPLES)
    ap.add_argument("--version", action="version", version=f"brdfcl {__version__}")
    ap.add_argument("--debug", action="store_true", help="show tracebacks")
    sub = ap.add_subparsers(dest="cmd", metavar="COMMAND", title="commands")    # Parser.parse_args asks for one
    common = Parser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks")
    add = sub.add_parser
    sub.add_parser = lambda *a, **kw: add(*a, parents=[common], formatter_class=HelpFormatter, **kw)
    device_help = "OpenCL device: an index or part of a name from brdfcl info (default: the one it marks chosen)"

    p = sub.add_parser("info", help="list the OpenCL devices, the one brdfcl uses, their vector widths and "
                                    "self-tests",
                       description="List every OpenCL platform and device, whether brdfcl can build its programs "
                                   "there and which device it uses by default (exit status 1 where none can be "
                                   "used); for each usable device, the vector width brdfcl runs at, why, and "
                                   "the result of its self-test.",
                       epilog="examples:\n  brdfcl info\n  brdfcl info --device 1")
    p.add_argument("--device", default=None, help=device_help)
    p.add_argument("--vector-width", type=int, default=None,
                   help="check this vector width instead of the one brdfcl chooses")
    p.set_defaults(func=cmd_info)

    n_demo = len(DEMO)
    p = sub.add_parser("synth", help=f"write a synthetic database to try brdfcl on ({n_demo} MERL tables of known "
                                     "parameters)",
                       description=f"Write the synthetic demo database to OUT: {n_demo} materials made from known "
                                   "parameters, as MERL .binary tables, and truth.json with those parameters "
                                   "(fit-all --demo fits the same materials). With --like FILE, write instead "
                                   f"{len(SPECTRAL)} synthetic spectral materials at the sample directions and "
                                   "wavelengths of a real measurement, as Cornell .brdf and .csv sample files, "
                                   "one folder per format.",
                       epilog="examples:\n  brdfcl synth merl/\n  brdfcl fit-all merl/ --out out/merl\n"
                              "  brdfcl synth merl-noisy/ --noise 0.01 --missing 0.01\n"
                              "  brdfcl synth --like krylon_blue.brdf --out spectral/")
    p.add_argument("out", nargs="?", default=None, help="output folder (or --out)")
    p.add_argument("--out", dest="out_flag", metavar="DIR", default=None, help="output folder")
    p.add_argument("--like", metavar="FILE", default=None,
                   help="a spectral measurement (.brdf, .csv): write the synthetic spectral materials at its "
                        "sample directions and wavelengths as scattered samples, instead of the MERL demo")
    p.add_argument("--formats", default=None,
                   help="with --like: comma-separated formats to write, brdf (Cornell) and/or csv (default "
                        f"{','.join(default_of(write_spectral_synth, 'formats'))})")
    p.add_argument("--noise", type=float, default=default_of(write_synth, "noise"),
                   help="relative Gaussian noise (default %(default)s; with --like each value is multiplied by "
                        "exp(noise * N(0, 1)))")
    p.add_argument("--missing", type=float, default=default_of(write_synth, "missing"),
                   help="fraction of cells marked missing (default %(default)s)")
    p.add_argument("--seed", type=int, default=default_of(write_synth, "seed"),
                   help="seed of the noise and missing cells (default %(default)s)")
    p.add_argument("--materials", default=None,
                   help=f"comma-separated subset of the demo materials ({', '.join(DEMO)}; with --like: of the "
                        f"spectral ones, {', '.join(SPECTRAL)})")
    p.set_defaults(func=cmd_synth)

    default_fit = default_fit_text(FitOptions().model, DEFAULT_FORMS)
    p = sub.add_parser("fit-all", help=f"fit every measurement of a folder: {formats_text()} (or --demo)",
                       description=f"Fit an analytic BRDF model to every measurement of a database folder: "
                                   f"{formats_text()} (in the folder itself, not "
                                   f"its subfolders), or to one such file, or to the demo database (--demo). "
                                   f"Without --model, {default_fit}. Writes OUT/NAME.json per material "
                                   "(parameters, errors, options), OUT/summary.csv and the report "
                                   "OUT/report/index.html. A run into an OUT that holds results made with the "
                                   "same options keeps them and fits only the rest.",
                       epilog="examples:\n  brdfcl fit-all merl/ --out out/merl\n  brdfcl fit-all --demo --out "
                              "out/demo\n  brdfcl fit-all merl/ --out out/ggx --model diffuse+diffraction+ggx\n"
                              "  brdfcl fit-all merl/ --out out/lobes --select-lobes --export-merl")
    add_database_arguments(p, "fit", "output folder, outside the input data (a rerun keeps the results "
                                      "made there with the same options)", fit_all,
                           model_help="fit this one model to every material, e.g. diffuse+ggx (brdfcl params "
                                      "MODEL lists its parameters); without --model: "
                                      + default_fit_text(FitOptions().model, DEFAULT_FORMS, short=True))
    p.add_argument("--export-merl", action="store_true",
                   help="also write each fit tabulated as a MERL table, OUT/NAME.binary")
    p.add_argument("--rgb", action="store_true",
                   help="fit spectral samples as linear sRGB (D65, CIE 1931 2 deg; needs colour-science: "
                        "pip install brdfcl[rgb]) instead of one channel per band")
    p.add_argument("--overwrite", action="store_true",
                   help="refit and replace results in --out that were made with other options "
                        "(without it such results stop the run)")
    p.add_argument("--select-lobes", action="store_true",
                   help="fit with and without each lobe, as brdfcl analyze compares them, and keep the lobes "
                        "each material needs")
    p.add_argument("--forms", default=None, metavar="FORMS",
                   help="fit each material's reflection lobe in each of these forms and keep the one of least "
                        "penalised error (as --select-lobes chooses lobes): NDF:FRESNEL pairs, e.g. "
                        "gtr:dielectric,abc:schlick, with NDF:SHADOWING:FRESNEL triples, e.g. "
                        "beckmann:vcavity:schlick, or every NDF with every Fresnel, e.g. ggx,gtr:schlick,dielectric; "
                        f"'none': the model as given (default: {DEFAULT_FORMS} unless --model or --fix is given)")
    p.add_argument("--published", default=None, metavar="CSV",
                   help="each material's best published fit and its rmse_log on the same table (columns "
                        "material, best_published, best_published_rmse_log; bench/bench_fit.py --published "
                        "writes them): the report names that fit and brdfcl's ratio to it")
    p.add_argument("--workers", type=int, default=0,
                   help="fit on a local Dask cluster of N workers (pip install brdfcl[cluster])")
    p.add_argument("--scheduler", default=None, help="fit on the Dask cluster at this address")
    p.set_defaults(func=cmd_fit_all)

    calibrate.add_parser(sub)

    p = sub.add_parser("analyze", help="test which materials show diffraction: gradient test, wavelength check, "
                                       "lobe comparison",
                       description=f"Test every material of a database folder ({formats_text()}) "
                                   "or of the demo database (--demo) for diffraction: the "
                                   "gradient test (tables only), the wavelength check and the lobe comparison "
                                   "(the model fitted with and without its diffraction and its reflection lobe). "
                                   "Writes each material's verdict and test results to OUT/analysis.csv, with "
                                   "maps (NAME.exr), figures and OUT/index.html, and the run's report in "
                                   "OUT/report/.",
                       epilog="examples:\n  brdfcl analyze merl/ --out out/analysis\n"
                              "  brdfcl analyze --demo --out out/demo-analysis")
    add_database_arguments(p, "analyse", "output folder", analyze,
                           model_help=f"the full model whose lobes are compared (default {FitOptions().model}; "
                                      "it needs a diffuse, a diffraction and a reflection lobe)")
    p.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser("export", help="write a finished fit for a renderer: BRDF Explorer, MERL table, Mitsuba 3, ALTA",
                       description="Write a finished fit (OUT/NAME.json written by fit-all) for a renderer, "
                                   "without fitting again: as a BRDF Explorer .brdf file (its analytic GLSL "
                                   "format), tabulated as a MERL .binary table, as Mitsuba 3 scene files (the "
                                   "brdfcl BSDF, and Mitsuba's own BSDFs where the fit maps onto them) and/or as "
                                   "an ALTA data file.",
                       epilog="examples (after brdfcl fit-all --demo --out out/demo):\n"
                              "  brdfcl export out/demo/synth-fabric.json --brdf-explorer fabric.brdf\n"
                              "  brdfcl export out/demo/synth-fabric.json --merl fabric-fit.binary\n"
                              "  brdfcl export out/demo/synth-fabric.json --mitsuba out/mitsuba\n"
                              "  brdfcl export out/demo/synth-fabric.json --alta fabric.alta --at points.alta")
    p.add_argument("fit", help="a NAME.json written by fit-all")
    p.add_argument("--brdf-explorer", metavar="PATH", help="write a BRDF Explorer .brdf file (analytic GLSL)")
    p.add_argument("--merl", metavar="PATH", help="write the fitted model tabulated as a MERL .binary")
    p.add_argument("--mitsuba", metavar="DIR",
                   help="write Mitsuba 3 files into DIR: the fit (NAME.json), NAME.xml, NAME-scene.xml, NAME.py "
                        "and, where the fit maps onto Mitsuba's own BSDFs, NAME-builtin.xml, "
                        "NAME-builtin-scene.xml and their textures (docs/mitsuba.md)")
    p.add_argument("--alta", metavar="PATH",
                   help="write the fitted model as an ALTA data file: at the points of the measurement it was "
                        "fitted to where that is readable, else on a RUSIN_TH_TD_PD grid (docs/outputs.md)")
    p.add_argument("--at", metavar="FILE", help="for --alta: at the points of this ALTA file instead, in its "
                                                "parametrisation and outputs")
    p.add_argument("--device", default=None, help=f"for --merl: {device_help}")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("terms", help="every D, G, F and PSD term with its parameters and source (Markdown)",
                       description="Print every term a model is built from (microfacet distributions D, "
                                   "shadowing G, Fresnel F, diffraction PSDs) with its parameters and the paper "
                                   "it comes from, as Markdown.",
                       epilog="example:\n  brdfcl terms > terms.md")
    p.set_defaults(func=cmd_terms)

    p = sub.add_parser("params", help="list a model's parameters, bounds and units",
                       description="List a model's lobes and parameters: each one's bounds, default, the range "
                                   "the global search draws from, whether it is searched in log space, its unit "
                                   "and meaning.",
                       epilog="examples:\n  brdfcl params\n  brdfcl params diffuse+gtr:smith:dielectric")
    p.add_argument("model", nargs="?", default=FitOptions().model, help="model string (default %(default)s)")
    p.set_defaults(func=cmd_params)
    return ap


def main(argv=None):
    ap = build_parser()
    args = ap.parse_args(argv)
    debug = getattr(args, "debug", False)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("brdfcl: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:                     # output piped into `head` and the like
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception as e:  # one line unless --debug
        if debug:
            raise
        from brdfcl.app.cluster import WorkerError
        from brdfcl.data.merl import MerlError
        from brdfcl.device.platforms import DeviceError
        from brdfcl.model.compose import ModelError
        known = (UsageError, MerlError, ModelError, DeviceError, OSError, ValueError, WorkerError)
        kind = "" if isinstance(e, known) else f"{type(e).__name__}: "
        text = " ".join(f"{kind}{e}".split())
        if len(text) > MESSAGE_CHARS:       # keep both ends: what failed, and where more is said
            text = f"{text[:MESSAGE_CHARS // 2 - 12].rstrip()} [...] {text[-(MESSAGE_CHARS // 2 - 12):].lstrip()}"
        if isinstance(e, UsageError):       # as argparse's usage errors (Parser.error)
            prog = f"brdfcl {args.cmd}"
            hint = "" if "did you mean" in text else f" (see {prog} --help)"
            print(f"{prog}: error: {text}{hint}", file=sys.stderr)
        else:
            print(f"brdfcl: error: {text}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
