/* Schlick 1994: F = F0 + (1 - F0) (1 - cos td)^5, F0 per channel. */
inline real_v fresnel_schlick(const cell_t *c, real F0, real_v *d_F0)
{
    *d_F0 = 1 - c->s5;
    return F0 + (1 - F0) * c->s5;
}
