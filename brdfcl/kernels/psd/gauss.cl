/* Gaussian PSD, kept for comparison ("it is never a Gaussian"): S = exp(-f^2/a^2). */
inline real_v psd_gauss(real_v f, real a, real_v *d_a)
{
    real_v x = (f / a) * (f / a);
    real_v S = exp(-x);
    *d_a = 2 * S * x / a;
    return S;
}
