"""Numbers the formulas' special functions are defined with, apart from SymPy: the float64
reference and the printers read them without importing the symbols."""

EXP_LIMIT = 40.0
"""exp_clamped's cap on its argument.  exp(-e^40) is 0 in float and double alike, so capping the
inner exponent of exp(-exp(x)) never changes a value, and e^40 ~ 2.4e17 times the normalisation
of a sharp lobe (~1e8) still fits a float, where e^80 overflowed into inf * 0 = NaN."""
