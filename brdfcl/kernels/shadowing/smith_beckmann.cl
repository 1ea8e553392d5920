/* Smith shadowing-masking for Beckmann (Walter et al. 2007, eq. 27; Heitz 2014, eq. 73):
 * a = 1 / (alpha tan t), Lambda = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2,
 * dLambda/dalpha = exp(-a^2) / (2 a sqrt(pi) alpha). */
inline real_v lambda_beckmann(real_v t2, real alpha, real_v *d_alpha)
{
    real_v a = 1 / (alpha * sqrt(t2));
    real_v e = exp(-a * a) / (a * (real)1.7724538509055160273);
    *d_alpha = e / (2 * alpha);
    return (e - erfc(a)) / 2;
}

inline real_v g_smith_beckmann(const cell_t *c, real alpha, real_v *d_alpha)
{
    real_v di, dl;
    real_v li = lambda_beckmann(c->t2i, alpha, &di), lo = lambda_beckmann(c->t2o, alpha, &dl);
    real_v G = 1 / ((1 + li) * (1 + lo));
    *d_alpha = -G * (di / (1 + li) + dl / (1 + lo));
    return G;
}

inline real_v g_smith_beckmann_hc(const cell_t *c, real alpha, real_v *d_alpha)
{
    real_v di, dl;
    real_v li = lambda_beckmann(c->t2i, alpha, &di), lo = lambda_beckmann(c->t2o, alpha, &dl);
    real_v G = 1 / (1 + li + lo);
    *d_alpha = -G * G * (di + dl);
    return G;
}
