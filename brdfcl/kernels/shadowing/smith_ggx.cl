/* Smith shadowing-masking for GGX (Walter et al. 2007, eq. 34; Heitz 2014, eq. 72 and 99).
 * Lambda(t2) = (sqrt(1 + alpha^2 t2) - 1) / 2, written without cancellation. */
inline real_v lambda_ggx(real_v t2, real alpha, real_v *d_alpha)
{
    real_v u = alpha * alpha * t2;
    real_v r = sqrt(1 + u);
    *d_alpha = alpha * t2 / (2 * r);
    return u / (2 * (1 + r));
}

/* Separable: G = G1(i) G1(o), G1 = 1 / (1 + Lambda). */
inline real_v g_smith_ggx(const cell_t *c, real alpha, real_v *d_alpha)
{
    real_v di, dl;
    real_v li = lambda_ggx(c->t2i, alpha, &di), lo = lambda_ggx(c->t2o, alpha, &dl);
    real_v G = 1 / ((1 + li) * (1 + lo));
    *d_alpha = -G * (di / (1 + li) + dl / (1 + lo));
    return G;
}

/* Height-correlated: G = 1 / (1 + Lambda(i) + Lambda(o)). */
inline real_v g_smith_ggx_hc(const cell_t *c, real alpha, real_v *d_alpha)
{
    real_v di, dl;
    real_v li = lambda_ggx(c->t2i, alpha, &di), lo = lambda_ggx(c->t2o, alpha, &dl);
    real_v G = 1 / (1 + li + lo);
    *d_alpha = -G * G * (di + dl);
    return G;
}
