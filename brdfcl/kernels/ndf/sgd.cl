/* Shifted gamma distribution (Bagher et al. 2012, eq. 6):
 * D = N(alpha, p) exp(-(alpha^2 + tan^2 th) / alpha) (alpha^2 + tan^2 th)^-p / cos^4 th,
 * N and its derivatives come from the host (brdfcl/lobes/ndf.py, sgd_consts). */
inline real_v ndf_sgd(const cell_t *c, real alpha, real p, real N, real dN_alpha, real dN_p,
                      real_v *d_alpha, real_v *d_p)
{
    real_v z = alpha * alpha + c->t2;
    real_v lz = log(z);
    real_v ch2 = c->ch * c->ch;
    real_v h = exp(-z / alpha - p * lz) / (ch2 * ch2);
    real_v hN = h * N;
    *d_alpha = h * dN_alpha + hN * (z / (alpha * alpha) - 2 - 2 * p * alpha / z);
    *d_p = h * dN_p - hN * lz;
    return N * h;
}
