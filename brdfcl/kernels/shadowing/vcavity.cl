/* V-cavity (Cook & Torrance 1982): min(1, 2 cos th cos ti / cos td, 2 cos th cos to / cos td),
 * parameter free, valid for any D; precomputed in make_cell. */
inline real_v g_vcavity(const cell_t *c) { return c->gv; }
