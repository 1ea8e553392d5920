"""Resuming a fit job in an output folder that already holds results.

A material whose NAME.json holds a successful fit made with the same options is finished: it is
not fitted again, and an export asked for now that it lacks is written without refitting.  An
unsuccessful one is fitted again.  A result made with other options (or by an older brdfcl that
did not record them) stops the run before any work (``ResultsDiffer``, one line naming the first
option that differs and how to go on, in the words of the caller) unless ``overwrite``, which fits
it again and replaces it.
"""
from __future__ import annotations

import json
from pathlib import Path

from brdfcl.app.runner import Runner
from brdfcl.data.merl import material_name
from brdfcl.report.output import resume_state
from brdfcl.report.writers import ExportWriter

# how to go on, in the Python API's words (the CLI passes its own to ResultsDiffer.message)
PROCEED = "to proceed, pass another out, or overwrite=True to refit and replace those results"


class ResultsDiffer(ValueError):
    """The output folder holds results made with other options than this run's.

    Its text is the Python API's (option names, ``overwrite=True``); `message` words it for another
    caller, which passes its own names: the CLI its flags (OPTION_FLAGS) and how to go on there."""

    def __init__(self, out: Path, differ: list, total: int, current: dict):
        self.out, self.differ, self.total, self.current = out, differ, total, current
        super().__init__(self.message())

    def message(self, flags: dict[str, str] | None = None, proceed: str = PROCEED) -> str:
        """One line: the first result that differs, the option (with its name in ``flags``,
        e.g. OPTION_FLAGS) and both values, how many more, then ``proceed``."""
        return _differ_message(self.out, self.differ, self.total, self.current, flags or {}, proceed)


# CLI flags of recorded options, for messages (a dotted name first, then its first part)
OPTION_FLAGS = {"model": "--model", "metric": "--metric", "cosw": "--no-cos", "cutoff_deg": "--cutoff",
                "real": "--double", "global_method": "--global", "n_candidates": "--candidates",
                "n_starts": "--starts", "lm.max_iter": "--max-iter", "seed": "--seed", "fixed": "--fix",
                "ct_peak": "--ct-peak", "select_lobes": "--select-lobes", "free_peak": "--free-peak",
                "forms": "--forms"}


def resume(run: Runner, options: dict, overwrite: bool) -> list[str]:
    """The paths of ``run`` (with an output folder) left to fit with ``options``
    (recorded_options); finished ones are listed in ``run.report.resumed``."""
    job = run.job
    assert job is not None, "resuming needs an output folder"
    exports = [w for w in run.writers if isinstance(w, ExportWriter)]
    todo, differ, pending, replaced = [], [], [], 0
    for p in run.paths:
        name = material_name(p)
        state, info = resume_state(job.out, name, options)
        if state == "done":
            run.report.resumed.append(name)
            missing = [w for w in exports if w.missing(job, name)]
            if missing:
                pending.append((info, missing))
        elif state == "differs" and not overwrite:
            differ.append((name, info))
        else:
            replaced += state == "differs"
            todo.append(p)
    if differ:
        raise ResultsDiffer(job.out, differ, len(run.paths), options)
    n = len(run.report.resumed)
    if n:
        run.log(f"resuming: {n} material{'s' * (n != 1)} already finished in {job.out}")
    if replaced:
        run.log(f"overwrite: refitting {replaced} result{'s' * (replaced != 1)} made with other options")
    for doc, writers in pending:
        for w in writers:
            w.export(w.path(job.out, doc["material"]), doc, job)
    if pending:
        run.log(f"exported {len(pending)} finished fit{'s' * (len(pending) != 1)} without refitting")
    return todo


def _differ_message(out: Path, differ: list, total: int, current: dict, flags: dict[str, str],
                    proceed: str) -> str:
    name, (option, old, new) = differ[0]
    where = out / f"{name}.json"
    many = f" (and {len(differ) - 1} more of the {total} materials)" if len(differ) > 1 else ""
    if option is None:
        what = "was written by an older brdfcl that did not record its options"
    else:
        flag = flags.get(option) or flags.get(option.split(".")[0])
        if flag and option == "ct_peak" and current.get("select_lobes"):    # --select-lobes sets it from --free-peak
            flag = flags.get("free_peak", flag)

        def show(v):
            plain = isinstance(v, (type(None), bool, int, float, str, list, dict))
            return json.dumps(v) if plain else "absent"
        what = (f"was made with other options: {option}{f' ({flag})' if flag else ''} is {show(old)} there, "
                f"{show(new)} now")
    return f"{where} {what}{many}; {proceed}"
