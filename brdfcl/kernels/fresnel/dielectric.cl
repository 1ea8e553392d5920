/* Exact unpolarised Fresnel reflectance of a dielectric (Cook & Torrance 1982, eq. in appendix;
 * Walter et al. 2007, eq. 22): g = sqrt(eta^2 - 1 + c^2), c = cos td,
 * F = 1/2 A^2 (1 + B^2), A = (g - c)/(g + c), B = (c (g + c) - 1)/(c (g - c) + 1). */
inline real_v fresnel_dielectric(const cell_t *c, real eta, real_v *d_eta)
{
    real_v cd = c->cd;
    real_v g = sqrt(eta * eta - 1 + cd * cd);
    real_v gp = g + cd, gm = g - cd;
    real_v A = gm / gp;
    real_v bn = cd * gp - 1, bd = cd * gm + 1;
    real_v B = bn / bd;
    real_v dA = 2 * cd / (gp * gp);
    real_v dB = 2 * cd * (1 - cd * cd) / (bd * bd);
    *d_eta = (eta / g) * (A * dA * (1 + B * B) + A * A * B * dB);
    return (real)0.5 * A * A * (1 + B * B);
}
