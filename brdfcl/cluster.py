"""Fitting on a Dask cluster: chunks of materials per task, results written as they arrive.

Each task fits a chunk of several materials in one batch (so every launch still
batches), on the worker's own OpenCL context: ``BRDFCL_DEVICE`` in the worker's
environment (or FitOptions.device) picks its device, e.g. one GPU per worker.
Results come back to the client, which writes them exactly as a single-process
run does.  A task whose worker dies is run again by the scheduler; each chunk's
results are written once, when its future completes, so nothing is lost or
duplicated.  Fits are deterministic per material whatever the chunking, so a
cluster run gives the same parameters as an in-process run.
"""
from __future__ import annotations

import math
import os

from .fit import FitOptions, Fitter, load_batch
from .run import FileReader, Models, result_writer


def make_client(scheduler=None, workers=0):
    """A Client for a scheduler address, or for a new local cluster of ``workers`` processes."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ImportError("the cluster mode needs Dask: pip install -e '.[cluster]'") from None
    if scheduler:
        return Client(scheduler)
    cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=True,
                           dashboard_address=None)
    client = Client(cluster)
    close = client.close

    def close_both(*a, **kw):
        close(*a, **kw)
        cluster.close()
    client.close = close_both
    return client


_WORKER_FITTERS: dict = {}


def fit_chunk(paths, opts: FitOptions):
    """Task body: fit a chunk on this worker; returns (results, {path: reason skipped})."""
    key = (repr(opts), os.environ.get("BRDFCL_DEVICE"))
    fitter = _WORKER_FITTERS.get(key)
    if fitter is None:
        fitter = _WORKER_FITTERS[key] = Fitter(opts)       # one context and program per worker
    skipped = {}

    def on_error(item, e):
        skipped[str(item)] = str(e)
    names, full, coarse = load_batch([FileReader(p) for p in paths], fitter, on_error)
    results = fitter.fit(names, full, coarse) if names else []
    return results, skipped


def fit_on_cluster(client, paths, out, opts, batch, export, report, log, quiet, t0):
    """Spread ``paths`` over the cluster's workers; fill ``report`` as chunks complete."""
    from dask.distributed import as_completed

    from .run import Progress, finish_run
    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    size = max(1, min(batch, math.ceil(len(paths) / (2 * n_workers))))
    chunks = [paths[i:i + size] for i in range(0, len(paths), size)]
    log(f"cluster: {len(chunks)} chunks of up to {size} materials on {n_workers} workers")
    futures = [client.submit(fit_chunk, c, opts, pure=False, retries=2) for c in chunks]
    progress = Progress(len(paths), quiet)
    writer = result_writer(out, Models(opts), export, report, progress)    # engine built only to export
    try:
        for fut in as_completed(futures):
            results, skipped = fut.result()
            report.skipped.update(skipped)
            for p, why in skipped.items():
                log(f"skipped: {why}")
            for r in results:
                writer(r)
    finally:
        finish_run(progress, out, report, t0)
    return report

