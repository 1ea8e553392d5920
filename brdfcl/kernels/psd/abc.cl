/* ABC / K-correlation PSD (Church & Takacs 1991; Low et al. 2012), B folded into a:
 * S = (1 + (f/a)^2)^(-(c+1)/2). */
inline real_v psd_abc(real_v f, real a, real c, real_v *d_a, real_v *d_c)
{
    real_v x = (f / a) * (f / a);
    real_v lu = log1p(x);
    real_v S = exp(-(c + 1) / 2 * lu);
    *d_a = S * (c + 1) * x / (a * (1 + x));
    *d_c = -(real)0.5 * lu * S;
    return S;
}
