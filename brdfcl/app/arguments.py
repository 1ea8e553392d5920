"""The flags fit-all and analyze share, and how they become FitOptions.

Every flag of `add_fit_arguments` is absent from the parsed arguments unless the user gave it
(argparse.SUPPRESS) and its help shows the default of the FitOptions / LMOptions field it sets, so
the command line holds no default that the options classes do not define: `fit_options` builds
FitOptions from the flags given, every other field keeping the class's own default.  Other
flags take their defaults from the function the command runs (`default_of`).
"""
from __future__ import annotations

import argparse
import functools
import inspect
from collections.abc import Callable
from dataclasses import fields, replace
from typing import Any

from brdfcl.data.readers import formats_text

NO_CUTOFF_DEG = 90.0    # --cutoff at or beyond the horizon: no cutoff (FitOptions.cutoff_deg None)


class UsageError(Exception):
    """A problem the user can fix, printed as one line."""


def _fixed(items):
    out = {}
    for it in items or []:
        k, sep, v = it.partition("=")
        try:
            out[k.strip()] = float(v)
        except ValueError:
            raise UsageError(f"--fix '{it}': expected NAME=VALUE, e.g. ct.eta=1.5") from None
        if not sep:
            raise UsageError(f"--fix '{it}': expected NAME=VALUE, e.g. ct.eta=1.5")
    return out


def fit_options(args: argparse.Namespace) -> Any:
    """FitOptions from the fit flags the user gave; every other field keeps FitOptions' default.

    The flags of `add_fit_arguments` are absent from ``args`` unless given (default SUPPRESS), and
    most are stored under their FitOptions field's name; the others are converted here."""
    from brdfcl.model.compose import Model
    from brdfcl.optim.fit import FitOptions
    given = vars(args)
    kw = {f.name: given[f.name] for f in fields(FitOptions) if f.name in given}
    if "cutoff" in given:
        kw["cutoff_deg"] = None if args.cutoff >= NO_CUTOFF_DEG else args.cutoff
    if "fix" in given:
        kw["fixed"] = _fixed(args.fix)
    if "max_iter" in given:
        kw["lm"] = replace(FitOptions().lm, max_iter=args.max_iter)
    opts = FitOptions(**kw)
    Model(opts.model, fixed=opts.fixed)             # clear error for a bad model before any work
    return opts


def default_of(func: Callable, name: str) -> Any:
    """The default of one of func's parameters: the CLI shows and uses it without repeating it."""
    return inspect.signature(func).parameters[name].default


def add_fit_arguments(p: argparse.ArgumentParser, model_help: str | None = None) -> None:
    """The flags that make FitOptions (see `fit_options`).  Their defaults are FitOptions' and
    LMOptions' own: a flag that is not given is absent from the parsed arguments, and its help
    shows the field's default.  ``model_help``: what --model does in this command (fit-all without
    it chooses a form per material, so FitOptions' model is not its default there)."""
    from brdfcl.model.metrics import IMPLEMENTED_METRICS, METRICS
    from brdfcl.optim.fit import GLOBAL_METHODS, FitOptions
    d = FitOptions()
    cutoff = "none" if d.cutoff_deg is None else f"{d.cutoff_deg:g}"
    real = {"float": "float32", "double": "float64"}.get(d.real, d.real)
    opt = functools.partial(p.add_argument, default=argparse.SUPPRESS)    # absent unless given
    opt("--model", help=model_help or f"model string (default {d.model})")
    opt("--metric", choices=METRICS, help=f"fit metric (default {d.metric}); "
        + "; ".join(f"{m.name}: {m.doc}" for m in IMPLEMENTED_METRICS.values()))
    opt("--no-cos", dest="cosw", action="store_false",
        help="no cos(theta_i) factor in the residual")
    opt("--cutoff", type=float,
        help="leave out cells with theta_i or theta_o beyond this angle "
             f"(degrees, {NO_CUTOFF_DEG:g} or more: none; default {cutoff})")
    opt("--double", dest="real", action="store_const", const="double",
        help=f"float64 kernels and data (default {real})")
    opt("--device", help="OpenCL device: an index or part of a name from brdfcl info (default: the one it "
                         "marks chosen)")
    opt("--vector-width", type=int, choices=(1, 2, 4, 8, 16),
        help="cells per work-item on a CPU (default: the widest that passes the self-test; "
             "also BRDFCL_VECTOR_WIDTH)")
    opt("--global", dest="global_method", choices=GLOBAL_METHODS,
        help=f"global search (default {d.global_method}); lds: Sobol candidates + nlopt L-BFGS starts")
    opt("--candidates", dest="n_candidates", metavar="CANDIDATES", type=int,
        help=f"Sobol candidates per material (lds; default {d.n_candidates})")
    opt("--starts", dest="n_starts", metavar="STARTS", type=int,
        help=f"local searches per material (lds; default {d.n_starts})")
    opt("--max-iter", type=int, help=f"Levenberg-Marquardt iterations (default {d.lm.max_iter})")
    opt("--fix", action="append", metavar="NAME=VALUE", help="hold a parameter fixed")
    opt("--ct-peak", action="store_true",
        help="Cook-Torrance carries the specular peak: the diffraction lobe may not exceed it "
             "there (always on in analyze and --select-lobes unless --free-peak)")
    p.add_argument("--free-peak", action="store_true", help="analyze, --select-lobes: no peak constraint")
    opt("--seed", type=int, help=f"seed of the global search (default {d.seed})")


def add_database_arguments(p: argparse.ArgumentParser, verb: str, out_help: str, job: Callable,
                           model_help: str | None = None) -> None:
    """What fit-all and analyze share: the database (or --demo), the output, the fit options.
    ``job``: the function the command runs (brdfcl.app.run.fit_all, brdfcl.app.analyze.analyze), whose
    defaults the other flags take; ``model_help``: see `add_fit_arguments`."""
    p.add_argument("database", nargs="?", default=None,
                   help=f"folder of measurements ({formats_text('or')}; not its subfolders) or one such file")
    p.add_argument("--demo", action="store_true", help=f"{verb} the embedded demo database")
    p.add_argument("--out", required=True, help=out_help)
    add_fit_arguments(p, model_help)
    p.add_argument("--batch", type=int, default=default_of(job, "batch"),
                   help="materials per batch (all share each launch; default %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or stage messages")
    p.add_argument("--no-report", action="store_true",
                   help="skip the run's report (OUT/report/: spheres, slices, comparison page)")
