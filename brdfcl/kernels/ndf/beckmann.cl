/* Beckmann (Walter et al. 2007, eq. 25):
 * D = exp(-tan^2 th / alpha^2) / (pi alpha^2 cos^4 th). */
inline real_v ndf_beckmann(const cell_t *c, real alpha, real_v *d_alpha)
{
    real a2 = alpha * alpha;
    real_v ch2 = c->ch * c->ch;
    real_v e = c->t2 / a2;
    real_v D = exp(-e) / (PI_R * a2 * ch2 * ch2);
    *d_alpha = D * (2 * e - 2) / alpha;
    return D;
}
