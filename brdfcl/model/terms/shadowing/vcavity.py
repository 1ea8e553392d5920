"""V-cavity shadowing (Cook & Torrance 1982): min(1, 2 cos th cos ti / cos td, 2 cos th cos to / cos td),
parameter free, for any D; a per-cell quantity (``gv``) computed once per cell."""
from brdfcl.model.terms.base import Term, register


def vcavity():
    from brdfcl.model.terms.symbols import gv
    return gv


register(Term("shadowing", "vcavity", (), vcavity, family="vcavity", cite="Cook & Torrance 1982",
              doc="V-cavity, any D"))
