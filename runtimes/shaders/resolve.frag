#version 300 es
// The realtime schedule's single full-screen pass: spectral → XYZ → display → dither → 8 bit.
// The same arithmetic as spectral_to_xyz.frag, display.frag and dither.frag run one after
// the other (the analysis schedule, which keeps the intermediate XYZ and drive images);
// fusing them saves two full-screen round trips through memory.  Kept in step with those
// files by tests/runtimes (both schedules must give identical 8-bit images).
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef TONE_KIND
#define TONE_KIND 0                 // 0 sRGB piecewise, 1 GOG, 2 LUT
#endif
#ifndef GAMUT_MAPPING
#define GAMUT_MAPPING 1             // 0 clip, 1 chroma (constant luminance toward the neutral)
#endif

uniform sampler2D u_radiance0;
uniform sampler2D u_radiance1;
uniform sampler2D u_radiance2;
uniform sampler2D u_radiance3;
uniform mat4x3 u_xyz_weights[4];

uniform float u_exposure;
uniform vec3 u_xyz_offset;
uniform mat3 u_xyz_to_rgb;
uniform vec4 u_tone_params[3];
uniform sampler2D u_tone_lut;
uniform int u_tone_lut_size;
uniform float u_inv_y_span;         // 1 / (Y_white − Y_black) of the display, cd/m²

uniform sampler2D u_noise;
uniform int u_noise_size;          // a power of two
uniform ivec4 u_noise_offsets;      // (x, y) offsets of channels G and B
uniform float u_dither_amplitude;

layout(location = 0) out vec4 o_rgba;

float srgb_encode(float x) {
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

float gog_inverse(float l, vec4 p) {
    return (pow(max(l, 0.0), 1.0 / p.z) - p.y) / p.x;
}

float lut_inverse(float l, int channel) {
    float x = clamp(l, 0.0, 1.0) * float(u_tone_lut_size - 1);
    int i0 = min(int(floor(x)), u_tone_lut_size - 2);
    float t = x - float(i0);
    float a = texelFetch(u_tone_lut, ivec2(i0, 0), 0)[channel];
    float b = texelFetch(u_tone_lut, ivec2(i0 + 1, 0), 0)[channel];
    return mix(a, b, t);
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 xyz = u_xyz_weights[0] * texelFetch(u_radiance0, p, 0)
             + u_xyz_weights[1] * texelFetch(u_radiance1, p, 0)
             + u_xyz_weights[2] * texelFetch(u_radiance2, p, 0)
             + u_xyz_weights[3] * texelFetch(u_radiance3, p, 0);

    xyz *= u_exposure;
    vec3 lin = u_xyz_to_rgb * (xyz - u_xyz_offset);
    float excess = max(max(max(-lin.r, -lin.g), -lin.b), max(max(lin.r, lin.g), lin.b) - 1.0);
#if GAMUT_MAPPING == 1
    if (excess > 1e-6) {
        // chroma mapping: toward the grey of the same luminance until every channel fits
        float g = clamp((xyz.y - u_xyz_offset.y) * u_inv_y_span, 0.0, 1.0);
        vec3 diff = lin - vec3(g);
        float s = 1.0;
        if (lin.r > 1.0) { s = min(s, (1.0 - g) / diff.r); }
        if (lin.r < 0.0) { s = min(s, g / -diff.r); }
        if (lin.g > 1.0) { s = min(s, (1.0 - g) / diff.g); }
        if (lin.g < 0.0) { s = min(s, g / -diff.g); }
        if (lin.b > 1.0) { s = min(s, (1.0 - g) / diff.b); }
        if (lin.b < 0.0) { s = min(s, g / -diff.b); }
        lin = vec3(g) + clamp(s, 0.0, 1.0) * diff;
    }
#endif
    lin = clamp(lin, 0.0, 1.0);
    // TONE_KIND is a compile-time constant (the runtime prepends #define TONE_KIND n for the
    // display's model): a branch on a uniform would run every branch on SIMD CPUs.
#if TONE_KIND == 1
    vec3 d = vec3(gog_inverse(lin.r, u_tone_params[0]), gog_inverse(lin.g, u_tone_params[1]),
                  gog_inverse(lin.b, u_tone_params[2]));
#elif TONE_KIND == 2
    vec3 d = vec3(lut_inverse(lin.r, 0), lut_inverse(lin.g, 1), lut_inverse(lin.b, 2));
#else
    vec3 d = vec3(srgb_encode(lin.r), srgb_encode(lin.g), srgb_encode(lin.b));
#endif
    d = clamp(d, 0.0, 1.0);

    // tile the mask: & (size − 1) is the modulo for a power-of-two size (integer division
    // is not vectorised on CPUs and dominated this pass on llvmpipe)
    int m = u_noise_size - 1;
    vec3 n = vec3(texelFetch(u_noise, p & m, 0).r,
                  texelFetch(u_noise, (p + u_noise_offsets.xy) & m, 0).r,
                  texelFetch(u_noise, (p + u_noise_offsets.zw) & m, 0).r);
    n = mix(vec3(0.5), n, u_dither_amplitude);
    o_rgba = vec4(clamp(floor(d * 255.0 + n), 0.0, 255.0) / 255.0, 1.0);
}
