/* GGX / Trowbridge-Reitz (Walter et al. 2007, eq. 33):
 * D = alpha^2 / (pi cos^4 th (alpha^2 + tan^2 th)^2). */
inline real_v ndf_ggx(const cell_t *c, real alpha, real_v *d_alpha)
{
    real a2 = alpha * alpha;
    real_v s = a2 + c->t2;
    real_v ch2 = c->ch * c->ch;
    real_v D = a2 / (PI_R * ch2 * ch2 * s * s);
    *d_alpha = D * (2 / alpha - 4 * alpha / s);
    return D;
}
