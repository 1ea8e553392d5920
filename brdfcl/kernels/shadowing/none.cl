/* No shadowing-masking (G = 1). */
inline real_v g_none(const cell_t *c) { return (real_v)1; }
