"""The NBRDF recipe in numpy: fit a 6-21-21-3 network to a MERL table, and tabulate it back.

This is how the MERL-proxy tables were made (``../shared/tools/merl_proxy.py`` and
``../shared/data/nbrdf/README.md``; Sztrajman, Rainer, Ritschel, Weyrich, "Neural BRDF
Representation and Importance Sampling", CGF 40(6), 2021, and their published training code),
so that the calibration (brdfcl.analysis.calibration) can send a synthetic table through the same
round trip and see what the tests lose:

* input encoding: the half vector with phi_h = 0 and the Rusinkiewicz difference vector,
  ``x = (sin th, 0, cos th, sin td cos pd, sin td sin pd, cos td)``;
* network: ``relu(x W1 + b1)``, ``relu(. W2 + b2)``, ``max(exp(. W3 + b3) - 1, 0)`` (6-21-21-3),
  weights uniform in [-0.05, 0.05], biases zero;
* training samples: angles uniform in theta_h, theta_d in [0, pi/2] and phi_d in [0, 2 pi) (not
  uniform in solid angle), each target the trilinear interpolation of the table with entry
  (i, j, k) anchored at its bin's lower edge ("node") and phi_d folded by reciprocity, samples
  whose red target is negative (a missing corner, stored as -1 as in MERL files) dropped;
  800,000 drawn, 80% used for training; the draw is the same for every material (the published
  script seeds numpy with 0 before each material);
* loss: mean absolute error of ``ln(1 + f cos theta_i)`` (cos theta_i clamped to [0, 1]) over the
  batch and the three channels;
* optimiser: Adam, learning rate 5e-4, betas (0.9, 0.999), eps 1e-15, batches of 512, reshuffled
  each epoch; the recipe runs 100 epochs (``TrainOptions.epochs``);
* tabulation: the network at each cell's node, missing (NaN) where the node's incident or outgoing
  direction is on or below the horizon, as merl_proxy.py writes -1 there.

Several materials train at once, each with its own network, on one shared draw of sample angles
(one launch of numpy per step for all of them); float32 as the published PyTorch code.

About 300 lines, one module: the network, its input encoding, its training loop and its
tabulation must agree on every detail of the recipe, and are read together.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from brdfcl.data.merl import N_CELLS, N_PD, N_TD, N_TH, SCALE

HIDDEN = 21
SHAPES = {"fc1": (6, HIDDEN), "b1": (HIDDEN,), "fc2": (HIDDEN, HIDDEN), "b2": (HIDDEN,),
          "fc3": (HIDDEN, 3), "b3": (3,)}
N_WEIGHTS = sum(int(np.prod(s)) for s in SHAPES.values())
HORIZON_EPS = 1e-9


@dataclass
class TrainOptions:
    """The NBRDF paper's training; ``epochs`` is the one knob the calibration turns down."""

    epochs: int = 100
    batch: int = 512
    learning_rate: float = 5e-4
    betas: tuple = (0.9, 0.999)
    eps: float = 1e-15
    n_samples: int = 800_000
    train_share: float = 0.8
    init_range: float = 0.05
    seed: int = 0


# --- geometry -----------------------------------------------------------------------------------
def encode(theta_h, theta_d, phi_d):
    """Network inputs (n, 6) from Rusinkiewicz angles (phi_h = 0)."""
    sh, ch = np.sin(theta_h), np.cos(theta_h)
    st, ct = np.sin(theta_d), np.cos(theta_d)
    return np.stack([sh, np.zeros_like(sh), ch, st * np.cos(phi_d), st * np.sin(phi_d), ct], axis=-1)


def cos_incident(theta_h, theta_d, phi_d):
    """cos theta_i for phi_h = 0 (merl_proxy.py's ``wi_z``)."""
    return np.cos(theta_d) * np.cos(theta_h) - np.sin(theta_d) * np.cos(phi_d) * np.sin(theta_h)


def node_angles():
    """theta_h, theta_d, phi_d of each bin's lower edge (the node), as merl_proxy.py's default."""
    th = 0.5 * np.pi * (np.arange(N_TH) / N_TH) ** 2
    td = 0.5 * np.pi * np.arange(N_TD) / N_TD
    pd = np.pi * np.arange(N_PD) / N_PD
    return th, td, pd


def _node_weights(x, nodes, idx):
    """fastmerl's pair weights: 1 - |node - x| / (sum of both distances)."""
    d0, d1 = np.abs(nodes(idx) - x), np.abs(nodes(idx + 1) - x)
    s = d0 + d1
    s = np.where(s > 0, s, 1.0)
    return 1.0 - d0 / s, 1.0 - d1 / s


def interpolate(stored, theta_h, theta_d, phi_d):
    """Trilinear interpolation (3, n) of a table of stored MERL numbers (-1 where missing) at the
    given angles, entries anchored at their nodes; the values times SCALE (NBRDF's fastmerl)."""
    phi = np.where(phi_d <= 0, phi_d + np.pi, phi_d)
    i = np.clip(np.floor(N_TH * np.sqrt(theta_h / (np.pi / 2))), 0, N_TH - 1)
    j = np.clip(np.floor(N_TD * theta_d / (np.pi / 2)), 0, N_TD - 1)
    k = np.clip(np.floor(N_PD * phi / np.pi), 0, N_PD - 1)
    i = np.minimum(i, N_TH - 2)
    j = np.minimum(j, N_TD - 2)
    wi = _node_weights(theta_h, lambda n: (n / N_TH) ** 2 * np.pi / 2, i)
    wj = _node_weights(theta_d, lambda n: n / N_TD * np.pi / 2, j)
    wk = _node_weights(phi, lambda n: n / N_PD * np.pi, k)
    i, j, k = i.astype(np.int64), j.astype(np.int64), k.astype(np.int64)
    out = np.zeros((3, theta_h.size))
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                kk = k + c
                kk = np.where(kk < N_PD, kk, 0)
                cell = kk + N_PD * ((j + b) + N_TD * (i + a))
                out += stored[:, cell] * (wi[a] * wj[b] * wk[c])[None]
    return out * SCALE[:, None]


def stored_numbers(brdf):
    """MERL's stored numbers (3, N_CELLS) of a BRDF table in 1/sr, -1 where missing."""
    s = np.asarray(brdf, dtype=np.float64) / SCALE[:, None]
    return np.where(np.isfinite(s), s, -1.0)


# --- network ------------------------------------------------------------------------------------
def unpack(flat):
    """{name: array} views of flat weight vectors (..., N_WEIGHTS)."""
    out, o = {}, 0
    for k, s in SHAPES.items():
        n = int(np.prod(s))
        out[k] = flat[..., o:o + n].reshape(flat.shape[:-1] + s)
        o += n
    return out


def pack(weights):
    """Flat vector (N_WEIGHTS,) of one network's {name: array}."""
    return np.concatenate([np.asarray(weights[k], dtype=np.float64).ravel() for k in SHAPES])


def evaluate(weights, x, chunk=65536):
    """The network (merl_proxy.py's nbrdf_eval) on inputs x (n, 6): BRDF (n, 3), float64."""
    w = {k: np.asarray(v, dtype=np.float64) for k, v in weights.items()}
    y = np.empty((x.shape[0], 3))
    for s in range(0, x.shape[0], chunk):
        a = np.maximum(x[s:s + chunk] @ w["fc1"] + w["b1"], 0.0)
        a = np.maximum(a @ w["fc2"] + w["b2"], 0.0)
        y[s:s + chunk] = np.maximum(np.expm1(a @ w["fc3"] + w["b3"]), 0.0)
    return y


@lru_cache(maxsize=1)
def node_inputs():
    """(inputs (n, 6) of the cells whose node is above the horizon, their table indices), once."""
    th, td, pd = node_angles()
    TH, TD, PD = (a.ravel() for a in np.meshgrid(th, td, pd, indexing="ij"))
    x = encode(TH, TD, PD)
    sh, ch = np.sin(TH), np.cos(TH)
    ok = (x[:, 5] * ch - x[:, 3] * sh > HORIZON_EPS) & (x[:, 5] * ch + x[:, 3] * sh > HORIZON_EPS)
    idx = np.flatnonzero(ok)
    x = np.ascontiguousarray(x[idx])
    x.setflags(write=False)
    return x, idx


def tabulate(weights):
    """The network as a BRDF table (3, N_CELLS) in 1/sr: evaluated at every cell's node, NaN where
    the node's directions are on or below the horizon (merl_proxy.py's table, read back)."""
    x, idx = node_inputs()
    out = np.full((3, N_CELLS), np.nan)
    out[:, idx] = evaluate(weights, x).T
    return out


# --- training -----------------------------------------------------------------------------------
@dataclass
class Training:
    """What ``train`` returns: one network per material and the loss per epoch."""

    weights: list            # [{name: float64 array}] per material
    snapshots: dict          # {epoch: [weights per material]} for the epochs asked for
    loss: np.ndarray         # (n_materials, epochs) mean training loss of each epoch
    test_loss: np.ndarray    # (n_materials,) the loss on the held-out 20% after training
    seconds: float


def draw_samples(opts: TrainOptions):
    """The shared sample angles: (train, test), each (theta_h, theta_d, phi_d) arrays."""
    rng = np.random.default_rng(opts.seed)
    n_train = int(opts.n_samples * opts.train_share)
    n_test = int(opts.n_samples * (1 - opts.train_share))

    def draw(n):
        a = rng.uniform([0.0, 0.0, 0.0], [np.pi / 2, np.pi / 2, 2 * np.pi], (n, 3)).T
        return a[0], a[1], a[2]
    return draw(n_train), draw(n_test)


def _targets(tables, angles):
    """Inputs (n, 6) float32, cos theta_i (n,), targets (M, n, 3) and masks (M, n) of the samples."""
    th, td, pd = angles
    x = encode(th, td, pd).astype(np.float32)
    c = np.clip(cos_incident(th, td, pd), 0.0, 1.0).astype(np.float32)
    ys, masks = [], []
    for t in tables:
        y = interpolate(stored_numbers(t), th, td, pd).T
        keep = y[:, 0] >= 0
        ys.append(np.where(keep[:, None], y, 0.0).astype(np.float32))
        masks.append(keep)
    return x, c, np.stack(ys), np.stack(masks)


def _loss_terms(P, x, c, y, m):
    """Forward pass for every material's network P (M, N_WEIGHTS) on shared inputs: the loss per
    material and what the backward pass needs."""
    w = unpack(P)
    z1 = np.matmul(x[None], w["fc1"]) + w["b1"][:, None]
    a1 = np.maximum(z1, 0)
    z2 = np.matmul(a1, w["fc2"]) + w["b2"][:, None]
    a2 = np.maximum(z2, 0)
    z3 = np.matmul(a2, w["fc3"]) + w["b3"][:, None]
    e = np.exp(np.minimum(z3, 30.0))
    out = np.maximum(e - 1, 0)
    oc = out * c[None, :, None]
    diff = np.log1p(oc) - np.log1p(y * c[None, :, None])
    n = np.maximum(m.sum(axis=1), 1).astype(np.float32) * 3          # valid rows x channels
    loss = (np.abs(diff) * m[..., None]).sum(axis=(1, 2)) / n
    return loss, (w, z1, a1, z2, a2, z3, e, oc, diff, n)


def _gradient(x, c, m, cache):
    w, z1, a1, z2, a2, z3, e, oc, diff, n = cache
    g = np.sign(diff) * m[..., None] * (c[None, :, None] / (1 + oc)) / n[:, None, None]
    dz3 = g * np.where(z3 > 0, e, 0)
    gW3 = np.matmul(a2.transpose(0, 2, 1), dz3)
    dz2 = np.matmul(dz3, w["fc3"].transpose(0, 2, 1)) * (z2 > 0)
    gW2 = np.matmul(a1.transpose(0, 2, 1), dz2)
    dz1 = np.matmul(dz2, w["fc2"].transpose(0, 2, 1)) * (z1 > 0)
    gW1 = np.einsum("bi,mbj->mij", x, dz1)
    M = z1.shape[0]
    return np.concatenate([gW1.reshape(M, -1), dz1.sum(1), gW2.reshape(M, -1), dz2.sum(1),
                           gW3.reshape(M, -1), dz3.sum(1)], axis=1)


def init_weights(n, opts: TrainOptions, rng):
    """n networks: weights uniform in [-init_range, init_range], biases zero (float32)."""
    P = np.zeros((n, N_WEIGHTS), dtype=np.float32)
    for k, v in unpack(P).items():
        if k.startswith("fc"):
            v[...] = rng.uniform(-opts.init_range, opts.init_range, v.shape)
    return P


def _weights(P):
    return [{k: np.asarray(v, dtype=np.float64).copy() for k, v in unpack(P[i]).items()} for i in range(P.shape[0])]


def train(tables, opts: TrainOptions | None = None, log=None, snapshots=()) -> Training:
    """Fit one network per BRDF table (3, N_CELLS), 1/sr, NaN where missing; all at once.
    ``snapshots``: epochs after which to keep a copy of the weights as well."""
    opts = opts or TrainOptions()
    t0 = time.perf_counter()
    rng = np.random.default_rng(opts.seed + 1)
    train_angles, test_angles = draw_samples(opts)
    x, c, y, m = _targets(tables, train_angles)
    M, n = y.shape[0], x.shape[0]
    P = init_weights(M, opts, rng)
    mom, vel = np.zeros_like(P), np.zeros_like(P)
    b1, b2 = opts.betas
    lr, eps = np.float32(opts.learning_rate), np.float32(opts.eps)
    history = np.zeros((M, opts.epochs))
    step = 0
    kept: dict = {}
    n_batches = n // opts.batch
    for epoch in range(opts.epochs):
        order = rng.permutation(n)
        total = np.zeros(M)
        for b in range(n_batches):
            sel = order[b * opts.batch:(b + 1) * opts.batch]
            xb, cb, yb, mb = x[sel], c[sel], y[:, sel], m[:, sel]
            loss, cache = _loss_terms(P, xb, cb, yb, mb)
            G = _gradient(xb, cb, mb, cache)
            step += 1
            mom *= b1
            mom += (1 - b1) * G
            vel *= b2
            vel += (1 - b2) * G * G
            P -= (lr / (1 - b1 ** step)) * mom / (np.sqrt(vel / (1 - b2 ** step)) + eps)
            total += loss
        history[:, epoch] = total / max(n_batches, 1)
        if epoch + 1 in snapshots:
            kept[epoch + 1] = _weights(P)
        if log:
            log(f"epoch {epoch + 1}/{opts.epochs}: mean loss {history[:, epoch].mean():.5f} "
                f"({time.perf_counter() - t0:.0f} s)")
    del x, c, y, m
    xt, ct, yt, mt = _targets(tables, test_angles)
    test = np.zeros(M)
    for s in range(0, xt.shape[0], 20000):
        part = slice(s, s + 20000)
        lt, _ = _loss_terms(P, xt[part], ct[part], yt[:, part], mt[:, part])
        test += lt * np.maximum(mt[:, part].sum(axis=1), 1)
    test /= np.maximum(mt.sum(axis=1), 1)
    return Training(_weights(P), kept, history, test, time.perf_counter() - t0)
