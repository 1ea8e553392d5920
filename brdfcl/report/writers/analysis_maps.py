"""NAME.exr: an analysed material's maps on the phi_d ~ 90 deg slice, for any EXR viewer.

One (90, 90) float32 image per quantity and channel (rows theta_h, columns theta_d; -1 where
there is no value): the gradient test's angle to grad f (``angle_f``, where significant) and
vote (``consistent``), and the measured and fitted values (``measured``, the lobe groups
``diffuse_diffraction`` and ``ct``, the ``full`` fit), named ``QUANTITY.CHANNEL`` (R, G, B for
three channels, else the channel's name, brdfcl.model.compose.Model.channels).  Scattered samples
have no such slice: no map is written for them.
"""
from __future__ import annotations

import numpy as np

from brdfcl.model.compose import Model
from brdfcl.report.files import write_exr
from brdfcl.report.writers.analysis_figures import of_samples
from brdfcl.report.writers.base import ANALYSIS, Item, Job, Writer

SLICES = ("measured", "diffuse_diffraction", "ct", "full")


def exr_channel(name: str) -> str:
    """The EXR name of a channel: R, G, B (what viewers show as colour), others as they are."""
    return {"r": "R", "g": "G", "b": "B"}.get(name, name)


class AnalysisMaps(Writer):
    name = "maps"

    def applies_to(self, job: Job) -> bool:
        return job.kind == ANALYSIS

    def write(self, job: Job, item: Item) -> None:
        a = item.analysis
        assert a is not None
        if of_samples(a):          # scattered samples: no grid
            return
        images = {}
        for c, ch in enumerate(map(exr_channel, Model(a.specs["full"]).channels)):
            images[f"angle_f.{ch}"] = np.where(a.gradient.significant[c], a.gradient.angle_f[c], np.nan)
            images[f"consistent.{ch}"] = a.gradient.consistent[c].astype(np.float32)
            for k in SLICES:
                images[f"{k}.{ch}"] = a.slices[k][c]
        write_exr(job.out / f"{a.name}.exr", images)
