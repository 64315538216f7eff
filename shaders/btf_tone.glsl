// btf_tone.glsl - what both programs of a scene share about light (doc/lighting.md):
// which lights are on, the environment's quadratic, its irradiance on a plain
// surface, exposure, tone mapping and sRGB encoding.
//
// Public:  vec3 btf_tone_irradiance(vec3 n)   the quadratic's irradiance / pi on a
//            Lambertian surface of world normal n (1 under a uniform radiance of 1)
//          vec3 btf_tone_map(vec3 lin, int op)   0 none, 1 neutral, 2 aces
//          vec3 btf_tone_srgb(vec3 lin)   linear -> sRGB-encoded (clamped to 0..1)
//          vec3 btf_tone_srgb_decode(vec3 v)   sRGB-encoded -> linear
//
// Host specialisation: BTF_POINT and BTF_ENV (0 or 1) compile only the light terms in
// use (a SIMD software rasteriser runs every branch); without them the uniforms
// u_point_off and u_env_on choose at run time. The host must set u_exposure (1: none).

uniform vec3 u_env_c0;    // the quadratic c0 + a.d + d^T Q d per channel (world), rotated by the host
uniform mat3 u_env_a;     // column ch: a of channel ch
uniform mat3 u_env_q[3];  // Q of channel ch
uniform int u_env_on;     // 1: environment light
uniform int u_point_off;  // 1: no point light (0, the default: u_light lights)
uniform float u_exposure; // linear scale before tone mapping
uniform int u_tone;       // 0 none, 1 neutral, 2 aces

#ifdef BTF_POINT
#define BTF__POINT (BTF_POINT == 1)
#else
#define BTF__POINT (u_point_off == 0)
#endif
#ifdef BTF_ENV
#define BTF__ENV (BTF_ENV == 1)
#else
#define BTF__ENV (u_env_on != 0)
#endif

// The cosine lobe's convolution of the quadratic, over pi: band 0 (c0 and the trace
// of Q over 3) times 1, band 1 (a) times 2/3, band 2 (Q less its trace) times 1/4.
vec3 btf_tone_irradiance(vec3 n)
{
    vec3 r;
    for (int ch = 0; ch < 3; ch++) {
        mat3 q = u_env_q[ch];
        float tr = (q[0][0] + q[1][1] + q[2][2]) / 3.0;
        r[ch] = u_env_c0[ch] + tr + 2.0 / 3.0 * dot(u_env_a[ch], n) + 0.25 * (dot(n, q * n) - tr);
    }
    return max(r, 0.0);
}

vec3 btf_tone_srgb_decode(vec3 v)
{
    v = max(v, 0.0);
    return mix(v / 12.92, pow((v + 0.055) / 1.055, vec3(2.4)), vec3(greaterThan(v, vec3(0.04045))));
}

vec3 btf_tone_srgb(vec3 lin)
{
    lin = clamp(lin, 0.0, 1.0);
    return mix(lin * 12.92, 1.055 * pow(lin, vec3(1.0 / 2.4)) - 0.055, vec3(greaterThan(lin, vec3(0.0031308))));
}

// Khronos PBR Neutral.
vec3 btf_tone_neutral(vec3 c)
{
    const float start = 0.8 - 0.04, desat = 0.15;
    float x = min(c.r, min(c.g, c.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    c -= offset;
    float peak = max(c.r, max(c.g, c.b));
    if (peak < start)
        return c;
    float d = 1.0 - start;
    float np = 1.0 - d * d / (peak + d - start);
    c *= np / peak;
    float g = 1.0 - 1.0 / (desat * (peak - np) + 1.0);
    return mix(c, vec3(np), g);
}

// The ACES fit as three.js applies it (columns of the matrices as written there).
vec3 btf_tone_aces(vec3 c)
{
    const mat3 to_ap1 = mat3(vec3(0.59719, 0.07600, 0.02840), vec3(0.35458, 0.90834, 0.13383),
                             vec3(0.04823, 0.01566, 0.83777));
    const mat3 from_ap1 = mat3(vec3(1.60475, -0.10208, -0.00327), vec3(-0.53108, 1.10813, -0.07276),
                               vec3(-0.07367, -0.00605, 1.07602));
    c = to_ap1 * (c / 0.6);
    vec3 a = c * (c + 0.0245786) - 0.000090537;
    vec3 b = c * (0.983729 * c + 0.4329510) + 0.238081;
    return clamp(from_ap1 * (a / b), 0.0, 1.0);
}

vec3 btf_tone_map(vec3 lin, int op)
{
    return op == 1 ? btf_tone_neutral(lin) : op == 2 ? btf_tone_aces(lin) : lin;
}
