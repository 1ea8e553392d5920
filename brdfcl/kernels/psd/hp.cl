/* The new PSD term of the talk (Holzschuch & Pacanowski): S = 1 / (1 + f^2/a^2)^2. */
inline real_v psd_hp(real_v f, real a, real_v *d_a)
{
    real_v x = (f / a) * (f / a);
    real_v u = 1 + x;
    real_v S = 1 / (u * u);
    *d_a = 4 * S * x / (a * u);
    return S;
}
