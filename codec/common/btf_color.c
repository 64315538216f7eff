/* btf_color.c - sRGB transfer functions and CIELab (D65). */
#include "btf_color.h"

#include <math.h>

double btf_color_srgb_decode(double v)
{
    return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

double btf_color_srgb_encode(double v)
{
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

/* Above this many values btf_color_srgb_decode_n tabulates the 256 byte values first. */
#define BTF__DECODE_TABLE_MIN 4096

void btf_color_srgb_decode_n(float *v, size_t n)
{
    float tab[256]; /* the byte values as the 8-bit sources write them (q * (1/255.0f)), decoded */
    int use_tab = n >= BTF__DECODE_TABLE_MIN;
    for (int q = 0; use_tab && q < 256; q++)
        tab[q] = (float)btf_color_srgb_decode((float)q * (1.0f / 255.0f));
    for (size_t i = 0; i < n; i++) {
        float x = v[i] * 255.0f;
        int q = x >= 0.0f && x <= 255.0f ? (int)lrintf(x) : -1;
        v[i] = q >= 0 && use_tab && v[i] == (float)q * (1.0f / 255.0f) ? tab[q] : (float)btf_color_srgb_decode(v[i]);
    }
}

void btf_color_srgb_encode_n(float *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        v[i] = isnan(v[i]) ? 0.0f : (float)btf_color_srgb_encode(v[i]);
}

void btf_color_srgb_to_lab(const float rgb[3], float lab[3])
{
    double lin[3];
    for (int c = 0; c < 3; c++) {
        double v = rgb[c] > 0.0f ? (rgb[c] < 1.0f ? rgb[c] : 1.0) : 0.0; /* NaN -> 0 */
        lin[c] = btf_color_srgb_decode(v);
    }
    double xyz[3] = {(0.4124564 * lin[0] + 0.3575761 * lin[1] + 0.1804375 * lin[2]) / 0.95047,
                     0.2126729 * lin[0] + 0.7151522 * lin[1] + 0.0721750 * lin[2],
                     (0.0193339 * lin[0] + 0.1191920 * lin[1] + 0.9503041 * lin[2]) / 1.08883};
    double f[3];
    for (int c = 0; c < 3; c++)
        f[c] = xyz[c] > 216.0 / 24389.0 ? cbrt(xyz[c]) : xyz[c] * (841.0 / 108.0) + 4.0 / 29.0;
    lab[0] = (float)(116.0 * f[1] - 16.0);
    lab[1] = (float)(500.0 * (f[0] - f[1]));
    lab[2] = (float)(200.0 * (f[1] - f[2]));
}
