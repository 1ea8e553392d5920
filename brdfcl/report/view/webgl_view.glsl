/* brdfcl's live view (brdfcl.report.view.webgl): the lit sphere of brdfcl.report.view.sphere, drawn
   with the BRDF above.  Camera: orthographic along -z, the unit sphere filling the canvas, x right,
   y up, z towards the viewer; normal n = (x, y, sqrt(1 - x^2 - y^2)) at the pixel centres; view
   direction (0, 0, 1); a directional light of unit irradiance from u_light:
   radiance = f(wi, wo) max(0, n.wi).  Defined VALUES: linear values as float bits (read back with
   readPixels): u_mode 0, the sphere's radiance; u_mode 1, the BRDF in the plane of incidence,
   light at azimuth 0 and theta_i = u_theta_i, theta_o from -90 to 90 deg over the canvas width
   (theta_o < 0 on the light's side, brdfcl.report.view.slices' convention), one pixel high. */
uniform vec2 u_size;
uniform vec3 u_light;
uniform float u_scale;
uniform int u_mode;
uniform float u_theta_i;

vec3 sphere_radiance(vec2 p, out bool inside)
{
    vec2 xy = p / u_size * 2.0 - 1.0;
    float r2 = dot(xy, xy);
    inside = r2 < 1.0;
    if (!inside)
        return vec3(0.0);
    vec3 n = vec3(xy, sqrt(max(1.0 - r2, 0.0)));
    /* any tangent frame: the lobes are isotropic */
    vec3 t = normalize(cross(abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0), n));
    return BRDF(u_light, vec3(0.0, 0.0, 1.0), n, t, cross(n, t)) * max(0.0, dot(n, u_light));
}

#ifdef VALUES
out uvec4 fragValue;
void main(void)
{
    if (u_mode == 0) {
        bool inside;
        vec3 r = sphere_radiance(gl_FragCoord.xy, inside);
        fragValue = uvec4(floatBitsToUint(r), inside ? 1u : 0u);
    } else {
        float to = radians(gl_FragCoord.x / u_size.x * 180.0 - 90.0);
        vec3 wi = vec3(sin(u_theta_i), 0.0, cos(u_theta_i));
        vec3 wo = vec3(-sin(to), 0.0, cos(to));
        vec3 f = BRDF(wi, wo, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0));
        fragValue = uvec4(floatBitsToUint(f), 1u);
    }
}
#else
out vec4 fragColor;
vec3 srgb(vec3 x)
{
    x = clamp(x, 0.0, 1.0);
    return mix(SRGB_SLOPE * x, SRGB_SCALE * pow(x, vec3(1.0 / SRGB_GAMMA)) - SRGB_OFFSET, step(SRGB_KNEE, x));
}
void main(void)
{
    bool inside;
    vec3 r = sphere_radiance(gl_FragCoord.xy, inside);
    fragColor = vec4(inside ? srgb(r * u_scale) : vec3(0.0), 1.0);
}
#endif
