/* No Fresnel factor (F = 1); the lobe's amplitude carries the reflectance. */
inline real_v fresnel_none(const cell_t *c) { return (real_v)1; }
