/* Exponential power distribution (Holzschuch & Pacanowski 2017):
 * D = N(beta, p) exp(-(tan^2 th / beta^2)^p) / cos^4 th, N = p / (pi beta^2 Gamma(1/p)) from the host.
 * The exponent is clamped where exp(-q) is already 0, and h q (<= 1/e / cos^4) is formed before
 * it meets the large factors, so that no inf reaches the products in float32. */
inline real_v ndf_epd(const cell_t *c, real beta, real p, real N, real dN_beta, real dN_p,
                      real_v *d_beta, real_v *d_p)
{
    real_v l = log(c->t2 / (beta * beta));
    real_v q = exp(fmin(p * l, (real)80));
    real_v ch2 = c->ch * c->ch;
    real_v h = exp(-q) / (ch2 * ch2);
    real_v hq = h * q;
    *d_beta = h * dN_beta + hq * (N * 2 * p / beta);
    *d_p = h * dN_p - hq * l * N;
    return N * h;
}
