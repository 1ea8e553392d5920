/* Exact unpolarised Fresnel reflectance of a conductor, eta + i k per channel
 * (the standard a^2 + b^2 form, e.g. Pharr, Jakob, Humphreys, PBR 3rd ed., sec. 8.2.1).
 * a^2 is formed without cancellation when eta^2 - k^2 - sin^2 td < 0. */
inline real_v fresnel_conductor(const cell_t *c, real eta, real k, real_v *d_eta, real_v *d_k)
{
    real_v cd = c->cd, c2 = cd * cd, s2 = 1 - c2;
    real_v t0 = eta * eta - k * k - s2;
    real_v S = sqrt(t0 * t0 + 4 * eta * eta * k * k);
    real_v a2 = SEL((S + t0) / 2, 2 * eta * eta * k * k / (S - t0), t0 < 0);
    real_v a = sqrt(a2);
    real_v dS_eta = 2 * eta * (t0 + 2 * k * k) / S, dS_k = 2 * k * (2 * eta * eta - t0) / S;
    real_v da_eta = eta * (a2 + k * k) / (a * S), da_k = k * (eta * eta - a2) / (a * S);
    real_v n = S + c2, m = 2 * a * cd;
    real_v Rs = (n - m) / (n + m);
    real_v u = c2 * S + s2 * s2, v = 2 * a * cd * s2;
    real_v Q = (u - v) / (u + v);
    real_v nm2 = (n + m) * (n + m), uv2 = (u + v) * (u + v);
    real_v dRs_eta = 2 * (m * dS_eta - n * 2 * cd * da_eta) / nm2;
    real_v dRs_k = 2 * (m * dS_k - n * 2 * cd * da_k) / nm2;
    real_v dQ_eta = 2 * (v * c2 * dS_eta - u * 2 * cd * s2 * da_eta) / uv2;
    real_v dQ_k = 2 * (v * c2 * dS_k - u * 2 * cd * s2 * da_k) / uv2;
    *d_eta = (real)0.5 * (dRs_eta * (1 + Q) + Rs * dQ_eta);
    *d_k = (real)0.5 * (dRs_k * (1 + Q) + Rs * dQ_k);
    return (real)0.5 * Rs * (1 + Q);
}
