"""`brdfcl calibrate --out DIR`: how much diffraction the tests see, and what the proxy hides.

The job: run (or resume) the study's cases into ``DIR/cases.csv``
(brdfcl.analysis.calibration_study), then summarise them (brdfcl.analysis.calibration_summary)
into figures (brdfcl.report.calibration_figures: ``power.png``, ``statistics.png``,
``verdict.png``) and ``DIR/calibration.md`` (brdfcl.report.calibration_markdown); and the
command's arguments.
"""
from __future__ import annotations

from pathlib import Path

from brdfcl.analysis.calibration import QUICK, Plan
from brdfcl.analysis.calibration_store import read_rows, read_timing
from brdfcl.analysis.calibration_study import CHUNK, DEFAULT_EPOCHS, QUICK_EPOCHS, run_cases
from brdfcl.analysis.calibration_summary import FP_TARGET, rule_text, summarise_rows
from brdfcl.optim.fit import FitOptions
from brdfcl.report.calibration_figures import write_figures
from brdfcl.report.calibration_markdown import markdown

__all__ = ["CHUNK", "DEFAULT_EPOCHS", "FP_TARGET", "QUICK", "QUICK_EPOCHS", "add_parser", "run", "study",
           "summarise"]


def study(out, plan: Plan | None = None, epochs: int = DEFAULT_EPOCHS, roundtrip: bool = True,
          fp: float = FP_TARGET, options: FitOptions | None = None, chunk: int = CHUNK, log=print):
    """Run (or resume) the study into ``out``; returns the summary (``summarise``)."""
    log = log or (lambda s: None)
    out = Path(out)
    timing = run_cases(out, plan or Plan(), epochs=epochs, roundtrip=roundtrip, options=options, chunk=chunk,
                       log=log)
    return summarise(out, read_rows(out / "cases.csv"), fp=fp, epochs=epochs, timing=timing, log=log)


def summarise(out, rows, fp=FP_TARGET, epochs=None, timing=None, log=print) -> dict:
    """Thresholds, power curves, false-positive rates, figures and calibration.md from the rows."""
    out = Path(out)
    if timing is None:
        timing = read_timing(out / "timing.json")
    s = summarise_rows(rows, fp)
    res = s.result
    res["markdown"] = str(out / "calibration.md")
    write_figures(out, s)
    (out / "calibration.md").write_text(markdown(s, fp, epochs, timing))
    if log:
        log(f"calibration: thresholds {', '.join(f'{k} {v:.4g}' for k, v in s.thresholds.items())}; "
            f"verdict rule: {rule_text(s.chosen)}")
    return res


def add_parser(subparsers):
    """The ``calibrate`` command on an argparse subparsers object."""
    p = subparsers.add_parser("calibrate", help="detection power and false positives of the diffraction tests "
                                                "on synthetic materials, before and after the NBRDF round trip",
                              description="Measure how well the diffraction tests of brdfcl analyze work: draw "
                                          "synthetic materials with and without a diffraction lobe (MERL-like "
                                          "noise and missing cells), analyse each as measured and, for some, "
                                          "after the NBRDF round trip (a small network trained on the table), "
                                          "and write the thresholds at the false-positive target, power curves "
                                          "and figures to OUT/calibration.md. Each analysed case is appended to "
                                          "OUT/cases.csv: a rerun resumes from it. --quick runs a handful of "
                                          "cases in minutes.",
                              epilog="examples:\n  brdfcl calibrate --quick --out out/calibration-quick\n"
                                     "  brdfcl calibrate --out out/calibration --no-roundtrip")
    p.add_argument("--out", required=True, help="output folder (cases.csv, figures, calibration.md); "
                                                "a rerun resumes the cases already in cases.csv")
    p.add_argument("--quick", action="store_true", help="a handful of cases and 2 training epochs (minutes)")
    p.add_argument("--no-roundtrip", action="store_true", help="skip the NBRDF round trip")
    p.add_argument("--epochs", type=int, default=None,
                   help=f"NBRDF training epochs (default {DEFAULT_EPOCHS}, {QUICK_EPOCHS} with --quick; "
                        "the recipe: 100)")
    p.add_argument("--fp", type=float, default=FP_TARGET, help="false-positive target (default %(default)s)")
    p.add_argument("--seed", type=int, default=Plan().seed, help="seed of the cases (default %(default)s)")
    p.add_argument("--device", default=None,
                   help="OpenCL device of the fits: an index or part of a name from brdfcl info (default: the one "
                        "it marks chosen)")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    plan = QUICK if args.quick else Plan()
    plan = Plan(**{**plan.__dict__, "seed": args.seed})
    epochs = args.epochs if args.epochs is not None else (QUICK_EPOCHS if args.quick else DEFAULT_EPOCHS)
    s = study(args.out, plan, epochs=epochs, roundtrip=not args.no_roundtrip, fp=args.fp,
              options=FitOptions(device=args.device))
    print(f"calibration: {s['markdown']}")
    return 0
