"""Smith shadowing-masking from a distribution's Lambda (Heitz 2014, Understanding the
masking-shadowing function, eq. 72 (separable) and 99 (height-correlated)).

For a distribution whose Lambda has no closed form (GTR, ABC), the exact Smith Lambda (Heitz 2014,
eq. 17 with the projected area of eq. 9: 1 + Lambda(o) = int max(0, o.m) D(m) dm / cos theta_o, so
Lambda(o) = int max(0, -o.m) D(m) dm / cos theta_o, the back-facing microfacets' projected area) is
evaluated by a fixed Gauss-Legendre rule, on the host, at the nodes of a short series in cos theta
that the kernels read (``SeriesLambda``).  With tau = tan theta_o and t = tan theta_m, the phi
integral in closed form gives (Heitz 2014, eq. 72's Lambda for an isotropic P22 = D cos^4 theta_m)

    Lambda(tau) = 2 int_{1/tau}^inf w(tau t) P22(t) t dt,   w(x) = sqrt(x^2 - 1) - arccos(1/x),

and, by parts, with P(t) the share of the projected microfacet area (D cos theta_m) beyond t,

    Lambda(tau) = (1/pi) int_{1/tau}^inf sqrt(tau^2 t^2 - 1) / t P(t) dt.

t = 1 / (tau cos b) maps both onto b in [0, pi/2) with smooth, bounded integrands:

    Lambda = (1/pi) int tan^2 b P db                                          (the share form)
           = 2 int (tan b - b) sin b cos b tau^2 D(theta_m) / (1 + tau^2 cos^2 b)^2 db  (the density form)

(P ~ 1/t^2 and D -> D(90 deg) in the tail).  They only read the distribution beyond the slope
1/tau >= cot 80 deg = 0.18, so the peak's width (alpha = 1e-4 or 1) never has to be resolved.  At the
nodes cos^2 theta_m = q = tau^2 cos^2 b / (1 + tau^2 cos^2 b).  The share form needs a closed-form
cumulative and is the more accurate for a given number of nodes; the density form needs only D.
The rules' errors (bench/lambda_gtr.py) are largest for rough lobes near theta_o = 80 deg, the
default angle cut-off of a fit; beyond it the integrands' features crowd into b -> pi/2 and a rule
underestimates Lambda: the relative error of G1 = 1/(1 + Lambda) grows to ~1e-2 at 85 deg, ~0.1 at
88 deg and ~1 at 89.5 deg (for the roughest lobes, where G1 itself is small).  GGX's
P(t) = alpha^2 / (alpha^2 + t^2) gives its closed form back, (sqrt(1 + alpha^2 tau^2) - 1) / 2.

A series given a ``box`` of its inputs takes its coefficients there from a table of the rule
(series_table.py), a tenth of the rule's time, within series_table.MAX_G1_ERROR of it in G1.
"""
from __future__ import annotations

import hashlib
import itertools
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from brdfcl.model.terms.shadowing.series_table import Box, CoefficientTable

if TYPE_CHECKING:
    import sympy as sp

CITE = "Walter et al. 2007; Heitz 2014, Understanding the masking-shadowing function"


class Direction(NamedTuple):
    """The cell symbols of one direction a Lambda reads: tan^2 theta and cos theta."""
    tan2: sp.Expr
    cos: sp.Expr


def incident() -> Direction:
    from brdfcl.model.terms.symbols import ci, t2i
    return Direction(t2i, ci)


def outgoing() -> Direction:
    from brdfcl.model.terms.symbols import co, t2o
    return Direction(t2o, co)


def separable(lam):
    """G = G1(i) G1(o), G1 = 1 / (1 + Lambda(direction)); ``lam(Direction, **inputs)``."""
    return lambda **p: 1 / ((1 + lam(incident(), **p)) * (1 + lam(outgoing(), **p)))


def correlated(lam):
    """G = 1 / (1 + Lambda(i) + Lambda(o))."""
    return lambda **p: 1 / (1 + lam(incident(), **p) + lam(outgoing(), **p))


def _nodes(n):
    """Gauss-Legendre nodes b_j and weights w_j on [0, pi/2]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return np.pi / 4 * (x + 1.0), np.pi / 4 * w


def density_weights(n):
    """(cos^2 b_j, weights) of the n-node rule on the density form: Lambda(tau) = sum_j weight_j
    ``density_integrand``(tau^2 cos^2 b_j)."""
    b, w = _nodes(n)
    return np.cos(b) ** 2, 2 * w * (np.tan(b) - b) * np.sin(b) / np.cos(b)


def density_integrand(u, density):
    """The density form's integrand at one node, u = tau^2 cos^2 b: 2 int (tan b - b) sin b cos b tau^2
    D / (1 + u)^2 db with cos b tau^2 / (1 + u)^2 = u r^2 / cos b, ``density(q, r)`` = D at
    cos^2 theta_m = q = u / (1 + u), r = 1 - q = 1 / (1 + u) (passed apart: no cancellation)."""
    return u * (1 / (1 + u)) ** 2 * density(u / (1 + u), 1 / (1 + u))


# ---- a Lambda without a closed form, as a short series in cos theta --------------------------------

SERIES_TERMS = 14
"""Chebyshev terms of a series Lambda (``SeriesLambda``)."""
SERIES_FROM_DEG = 88.0
"""The series interpolates cos theta over [cos SERIES_FROM_DEG, 1]; beyond, it extrapolates."""
HOST_NODES = 24
"""Nodes of the rule the host evaluates at the series' nodes (``density_weights``)."""
MEMO = 1 << 15
"""Parameter vectors outside its table whose coefficients a series Lambda keeps (``SeriesLambda.host_consts``)."""

_COS_LO = float(np.cos(np.radians(SERIES_FROM_DEG)))
_X = np.cos(np.pi * (np.arange(SERIES_TERMS) + 0.5) / SERIES_TERMS)        # Chebyshev nodes in x
_COS = _COS_LO + (_X + 1.0) / 2.0 * (1.0 - _COS_LO)                        # ... in cos theta
_CHEB = (np.where(np.arange(SERIES_TERMS) == 0, 1.0, 2.0)[:, None] / SERIES_TERMS
         * np.cos(np.outer(np.arange(SERIES_TERMS), np.pi * (np.arange(SERIES_TERMS) + 0.5) / SERIES_TERMS)))
"""Values at the nodes -> Chebyshev coefficients (interpolation: c_m = (2 - [m = 0]) / K sum_j f_j T_m(x_j))."""
_TO_COEF = np.stack([np.polynomial.chebyshev.cheb2poly(row) for row in _CHEB.T], axis=1)
"""Values at the nodes -> the same polynomial's coefficients of x^k (what a cell reads, by Horner)."""


class _Nodes(NamedTuple):
    """The cell quantities the host's integrand reads at the rule's points (an outgoing direction
    of tan^2 theta = u at each pair of series node and rule node)."""
    ch: np.ndarray
    co: np.ndarray
    t2o: np.ndarray


class SeriesLambda:
    """Lambda(theta) = base(theta) + S(cos theta) / cos theta, S the polynomial of degree
    SERIES_TERMS - 1 in x = 2 (cos theta - cos 88 deg) / (1 - cos 88 deg) - 1 that interpolates
    cos theta (Lambda - base) at the Chebyshev nodes in x.

    For a distribution whose Lambda has no closed form, a fixed rule per cell costs a log and an exp
    at each node, twice per cell and evaluation, which would make those kernels several times
    slower than GGX's.  The
    series moves the rule to the host: per evaluation (one parameter vector) the host evaluates the
    density form's rule (HOST_NODES Gauss-Legendre nodes, ``density_weights``) on ``integrand``
    (float64, its derivatives from SymPy) at the series' SERIES_TERMS nodes in cos theta and
    interpolates, giving the coefficients c_k of x^k and
    their derivatives by each input as host constants; a cell pays a Horner scheme.  The Chebyshev
    coefficients of a smooth function fall fast, so the x^k coefficients stay small and Horner's sum
    loses no more than a few float roundings.
    cos theta S = cos theta (Lambda - base) is smooth in cos theta (Lambda ~ tan theta near grazing),
    which makes a short series accurate: its error against the exact Lambda is measured by
    bench/lambda_gtr.py.  ``base(direction, **inputs)`` is a closed form the series corrects (GGX's
    Lambda for GTR, 0 for none), ``integrand(u, **inputs)`` the density form's integrand of
    Lambda - base at one node of the rule (``density_integrand``; u = tan^2 theta cos^2 b), ``origin``
    the module that defines them (the host rule's generated code is keyed by it).  The host evaluates
    the integrand once at every pair of series node and rule node, as one array, and sums the rule
    by a matrix product: a few dozen numpy operations per launch, whatever HOST_NODES is."""

    def __init__(self, name: str, inputs: tuple[str, ...], base, integrand, origin: str, box: Box | None = None):
        from brdfcl.model.terms.base import Term
        self.base, self.inputs, self.box = base, tuple(inputs), box
        self._table: CoefficientTable | None = None
        self.host = tuple(f"c{k}" for k in range(SERIES_TERMS))
        self.integrand = Term("shadowing", f"{name}_integrand", (), lambda **p: integrand(outgoing().tan2, **p),
                              uses=self.inputs, origin=origin)
        cos2_b, self._weights = density_weights(HOST_NODES)
        u = ((1.0 - _COS ** 2) / _COS ** 2)[:, None] * cos2_b          # (series node, rule node)
        co = 1.0 / np.sqrt(1.0 + u.ravel())                              # a direction with tan^2 = u
        self._points = _Nodes(co, co, u.ravel())
        self._memo: dict[bytes, np.ndarray] = {}

    def host_consts(self, **inputs):
        """({c_k: value}, {c_k: {input: derivative}}), float64, for inputs of any (equal) shape
        (c_k: the coefficient of x^k).

        The rule is most of a launch's host time for these models: inside ``box`` the coefficients
        come from its table instead (`table`, a tenth of the rule's time); outside, a fit asks again
        for many parameter vectors it has had (a search's optima ranked on other cells, a preview's
        result on the full table, the assessment and the report of the final fits), so each of
        those vectors' coefficients is kept (`_remembered`) and computed once."""
        at = np.broadcast_arrays(*(np.asarray(inputs[k], dtype=np.float64) for k in self.inputs))
        shape = at[0].shape
        rows = np.stack([a.ravel() for a in at], axis=1)
        table = np.empty((rows.shape[0], 1 + len(self.inputs), SERIES_TERMS))
        tab = self.table()
        inside = tab.covers(rows) if tab is not None else np.zeros(rows.shape[0], dtype=bool)
        if inside.any():
            table[inside] = tab(rows[inside])
        rest = np.flatnonzero(~inside)
        if rest.size:
            table[rest] = self._remembered(rows[rest])
        table = table.reshape(*shape, 1 + len(self.inputs), SERIES_TERMS)
        return ({c: table[..., 0, k] for k, c in enumerate(self.host)},
                {c: {p: table[..., 1 + j, k] for j, p in enumerate(self.inputs)} for k, c in enumerate(self.host)})

    def table(self) -> CoefficientTable | None:
        """The coefficients tabulated over ``box`` (series_table), made once per machine from the
        rule and read once per process; None without a box."""
        if self.box is None:
            return None
        if self._table is None:
            from brdfcl._cache import generated_arrays
            from brdfcl.model.terms.keys import formula_key
            # the integrand's key follows every module of the terms (this one and series_table too)
            key = hashlib.sha1(f"{formula_key(self.integrand)}\0{self.box.key()}".encode()).hexdigest()[:24]
            arrays = generated_arrays(f"series-{self.integrand.name}", key,
                                      lambda: CoefficientTable.build(self.box, self._coefficients))
            self._table = CoefficientTable(self.box, arrays)
        return self._table

    def _remembered(self, rows):
        """`_coefficients` of rows the table does not cover: each vector's kept (`MEMO` at most,
        the oldest dropped first) and computed once."""
        keys = [r.tobytes() for r in rows]
        memo = self._memo
        new: dict[bytes, int] = {}
        for i, k in enumerate(keys):
            if k not in memo and k not in new:
                new[k] = i
        made = dict(zip(new, self._coefficients(rows[list(new.values())]))) if new else {}
        out = np.stack([memo[k] if k in memo else made[k] for k in keys])
        memo.update(made)
        if len(memo) > MEMO:
            for k in list(itertools.islice(memo, len(memo) - MEMO // 2)):
                del memo[k]
        return out

    def __getstate__(self):
        return {**self.__dict__, "_memo": {}, "_table": None}     # what it keeps stays in its process

    def _coefficients(self, rows):
        """(m, 1 + inputs, SERIES_TERMS): the x^k coefficients and their derivatives by each input
        at the parameter rows (m, inputs), from the host's rule."""
        m = rows.shape[0]
        at = {k: np.ascontiguousarray(rows[:, j])[:, None] for j, k in enumerate(self.inputs)}
        value, deriv = self.integrand.reference(self._points, **at)

        def coefficients(v):
            on_nodes = np.broadcast_to(v, (m, self._points.t2o.size)).reshape(m, SERIES_TERMS, -1) @ self._weights
            return (_COS * on_nodes) @ _TO_COEF.T
        return np.stack([coefficients(v) for v in (value, *(deriv[p] for p in self.inputs))], axis=1)

    def __call__(self, d: Direction, **p):
        """Lambda in the direction ``d``: ``p`` holds the inputs and the coefficients c_k."""
        import sympy as sp
        x = (d.cos - _COS_LO) * sp.Float(2.0 / (1.0 - _COS_LO)) - 1
        series = sp.Integer(0)
        for c in reversed(self.host):
            series = p[c] + x * series
        return self.base(d, **{k: p[k] for k in self.inputs}) + series / d.cos


def register_series(series: SeriesLambda, ndf: str, cite: str) -> None:
    """Register the separable (``smith_NDF``) and height-correlated (``smith_NDF_hc``) Smith terms
    of a series Lambda, for the distribution ``ndf``."""
    from brdfcl.model.terms.base import Term, register
    doc = f"Smith for {ndf.upper()}, exact Lambda as a {SERIES_TERMS}-term series"
    for suffix, form, kind, family in (("", separable, "separable", "smith"),
                                       ("_hc", correlated, "height-correlated", "smith-hc")):
        register(Term("shadowing", f"smith_{ndf}{suffix}", (), form(series), uses=series.inputs, ndfs=(ndf,),
                      family=family,
                      host=series.host, host_consts=series.host_consts, cite=cite, doc=f"{kind} {doc}",
                      origin=series.integrand.origin))
