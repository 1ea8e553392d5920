"""Fitting on a Dask cluster: chunks of materials per task, results written as they arrive.

Each task fits a chunk of several materials in one batch (so every launch still
batches), on the worker's own OpenCL context: ``BRDFCL_DEVICE`` in the worker's
environment (or FitOptions.device) picks its device, e.g. one GPU per worker.
Results come back to the client, which writes them exactly as a single-process
run does.  A task whose worker dies is run again by the scheduler; each chunk's
results are written once, when its future completes, so nothing is lost or
duplicated.  Fits are deterministic per material whatever the chunking, so a
cluster run gives the same parameters as an in-process run.

A failure inside a task (an OpenCL error, a device that is not there) comes back
as a value, not as a task exception, so that neither Dask's logs nor its retries
repeat it: the client stops the run with one line naming the chunk's materials,
the worker and the cause (WorkerError), whose ``__cause__`` holds the worker's
traceback (shown by ``brdfcl --debug``).  Importing this module does not import Dask
(only the functions that need it do), so it loads where Dask is not installed.

brdfcl.app.run calls ``fit_on_cluster``; what it shares with an in-process run (skipped files,
writers, progress) is the job runner's (brdfcl.app.runner), never brdfcl.app.run's.
"""
from __future__ import annotations

import logging
import math
import os
import traceback

from brdfcl._words import count
from brdfcl.app.runner import Runner
from brdfcl.data.errors import DataError
from brdfcl.data.merl import MerlError, material_name
from brdfcl.data.readers import read_measurement
from brdfcl.data.rgb import to_rgb
from brdfcl.model.compose import Model
from brdfcl.optim import fit
from brdfcl.optim.forms import FormFitter


class WorkerError(RuntimeError):
    """A chunk failed on a worker (or the cluster lost it): one line naming its materials and the cause."""


class RemoteTraceback(Exception):
    """The worker's traceback as text, the ``__cause__`` of a WorkerError (as concurrent.futures does)."""

    def __str__(self):
        return "\n" + self.args[0].rstrip()


def describe_error(e) -> str:
    """``Type: message`` on one line; pyopencl errors by their routine and error name, not their repr."""
    text = str(e)                   # pyopencl.Error: "create_buffer failed: INVALID_BUFFER_SIZE"
    record = getattr(e, "what", None)                # a pyopencl.Error holds an _ErrorRecord
    if (not text.strip() or "_ErrorRecord" in text) and record is not None \
            and callable(getattr(record, "routine", None)):
        text = f"{record.routine()} failed with code {record.code()}"
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    first = lines[0] if len(lines) < 2 else lines[0].rstrip(" :;,") + " [...]"
    kind = type(e).__name__
    if type(e).__module__.startswith("pyopencl"):
        kind = f"pyopencl.{kind}"
    return f"{kind}: {first}" if first else kind


def chunk_label(paths, most=3) -> str:
    names = [material_name(p) for p in paths]
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return ", ".join(names[:most]) + more


def make_client(scheduler=None, workers=0, log_level=logging.CRITICAL):
    """A Client for a scheduler address, or for a new local cluster of ``workers`` processes whose
    Dask logging (and the client's) shows only records of ``log_level`` and above: a failed chunk is
    reported once, by brdfcl, not by every process that saw it.  A script that starts a local cluster
    must do it under ``if __name__ == "__main__":`` (its workers are started by importing it again)."""
    try:                                    # local: Dask is optional (the "cluster" extra)
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ImportError("the cluster mode needs Dask: pip install -e '.[cluster]'") from None
    if scheduler:
        return Client(scheduler)
    cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=log_level)
    client = Client(cluster)
    close = client.close

    def close_both(*a, **kw):
        close(*a, **kw)
        cluster.close()
    client.close = close_both
    return client


_WORKER_FITTERS: dict = {}


def fit_chunk(paths, opts, forms=None, lambdas=None, rgb=False):
    """Task body: fit a chunk on this worker (``forms``: {key: model spec}, each material's form
    chosen as brdfcl.optim.forms.FormFitter does; ``lambdas``: the chunk's channels, None for
    R, G, B; ``rgb``: spectral files read as linear sRGB); returns ([(result, what NAME.json records
    beside it)], {path: reason skipped}, failure), failure None or (one line: worker and cause, the
    worker's traceback as text)."""
    try:
        key = (repr(opts), repr(forms), lambdas, os.environ.get("BRDFCL_DEVICE"))
        fitter = _WORKER_FITTERS.get(key)
        if fitter is None:                  # fit.Fitter looked up now: tests put a failing one there
            # one context and program per worker (and form)
            fitter = _WORKER_FITTERS[key] = (fit.Fitter(opts, lambdas=lambdas) if not forms
                                             else FormFitter(opts, forms, lambdas=lambdas))
        skipped = {}
        measurements = []
        for p in paths:
            try:
                m = read_measurement(p)
                measurements.append(to_rgb(m) if rgb else m)
            except (DataError, MerlError, ValueError) as e:
                skipped[str(p)] = str(e)

        def on_error(m, e):
            skipped[m.path or m.name] = str(e)
        done = fitter.fit(measurements, on_error=on_error) if measurements else []
        results = [r if isinstance(r, tuple) else (r, None) for r in done]
        return results, skipped, None
    except Exception as e:          # pyopencl errors do not even pickle: send text
        return [], {}, (f"on worker {_worker_name()}: {describe_error(e)}", traceback.format_exc())


def _worker_name():
    try:                                    # local: Dask is optional; on a worker it is there
        from distributed import get_worker
        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def _cancel(client, futures):
    try:
        client.cancel(futures)
    except Exception:       # a client that lost its scheduler: the run stops anyway
        pass


def fit_on_cluster(client, run: Runner, paths: list[str], opts: fit.FitOptions, batch: int,
                   forms: dict | None = None, rgb: bool = False) -> None:
    """Spread ``paths`` over the cluster's workers (``forms``: as `fit_chunk`), in chunks of
    measurements that can share a batch (brdfcl.app.runner.Runner.read); ``run`` writes each
    chunk's results as it completes."""
    # local: Dask is optional (the "cluster" extra); a caller with a client has it
    from dask.distributed import as_completed

    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    groups = run.read(paths, rgb)
    total = sum(len(g) for g in groups)
    size = max(1, min(batch, math.ceil(total / (2 * n_workers))))
    default = tuple(Model(opts.model).lambdas)
    chunks = []
    for g in groups:
        lambdas = tuple(float(x) for x in g[0].wavelengths)
        for i in range(0, len(g), size):
            chunks.append(([m.path for m in g[i:i + size]], None if lambdas == default else lambdas))
    run.log(f"cluster: {count(len(chunks), 'chunk')} of up to {count(size, 'material')} on "
            f"{count(n_workers, 'worker')}")
    futures = [client.submit(fit_chunk, c, opts, forms, lam, rgb, pure=False, retries=2) for c, lam in chunks]
    chunk_of = {f.key: c for f, (c, _) in zip(futures, chunks)}
    with run.tracking(total):
        for fut in as_completed(futures):
            chunk = chunk_of[fut.key]
            what = f"cluster: fitting {chunk_label(chunk)} ({len(chunk)} material{'s' * (len(chunk) != 1)})"
            try:
                results, skipped, failure = fut.result()
            except Exception as e:      # lost workers (KilledWorker), a task that could not start...
                _cancel(client, futures)
                raise WorkerError(f"{what} failed: {describe_error(e)}") from e
            if failure:
                _cancel(client, futures)
                raise WorkerError(f"{what} failed {failure[0]}") from RemoteTraceback(failure[1])
            for path, why in skipped.items():
                run.skip(path, why)
            for r, record in results:
                run.fitted(r, record)
