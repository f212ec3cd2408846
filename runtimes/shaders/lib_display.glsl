// lbscene shader library (a GLSL ES 3.00 chunk without #version): the display model.
//   display XYZ  = exposure · A · XYZ                  (cd·m⁻²); A: chromatic adaptation from the
//                                                      lighting's white to the display's (CAT16, or
//                                                      the identity: lbscene.engine.colour.adaptation)
//   linear RGB   = M · (display XYZ − offset)          offset: black level + reflected ambient
//   drive        = tone⁻¹(linear RGB)                  sRGB piecewise, GOG or a LUT
// The steps up to linear RGB, with the relative luminance y = (display Y − offset Y)/(Y_white −
// Y_black) that the roll-off and the gamut mapping need, are one affine map of XYZ, composed on
// the CPU: (linear RGB, y) = u_display_linear · (XYZ, 1) (display_linear).  Being affine, it may
// be applied per vertex and interpolated (surface.vert VERTEX_XYZ 1): display_drive_linear
// finishes the pixel from there.
// Out of gamut (a linear channel outside 0..1): GAMUT_MAPPING 1 (default) moves the colour
// toward the display's grey of the same luminance until it fits (lbscene.engine.colour.
// display_model's 'chroma' mapping), 0 clips each channel; the largest excess is returned
// in .a so the runtime can report it.  HIGHLIGHT_ROLLOFF 1 (on for samples with flakes): before
// that, luminance above u_highlight_knee of the white is compressed so that glints up to
// u_highlight_max × white keep distinct levels (highlight_rolloff).
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef TONE_KIND
#define TONE_KIND 0                 // 0 sRGB piecewise, 1 GOG, 2 LUT
#endif
#ifndef GAMUT_MAPPING
#define GAMUT_MAPPING 1             // 0 clip, 1 chroma (constant luminance toward the neutral)
#endif
#ifndef HIGHLIGHT_ROLLOFF
#define HIGHLIGHT_ROLLOFF 0         // 1: luminance above u_highlight_knee × white rolled off (glints)
#endif

uniform mat4 u_display_linear;      // (XYZ, 1) → (linear RGB, y): exposure, adaptation, offset, M
uniform vec4 u_tone_params[3];      // GOG per channel: (gain, offset, gamma, 0): L = (gain·d + offset)^gamma
uniform sampler2D u_tone_lut;       // (size × 1): drive for linear value i/(size − 1), per channel
uniform int u_tone_lut_size;
uniform float u_highlight_knee;     // HIGHLIGHT_ROLLOFF: start of the roll-off (fraction of white)
uniform float u_highlight_max;      // HIGHLIGHT_ROLLOFF: luminance (× white) brought to white

// Relative luminance y (1 = display white) → y' ≤ 1: identity up to the knee k, then extended
// Reinhard on the excess x = (y − k)/(1 − k) with white point w = (y_max − k)/(1 − k):
// x' = x (1 + x/w²)/(1 + x), so y_max maps to white and brighter glints stay brighter below it.
float highlight_rolloff(float y) {
    float k = u_highlight_knee;
    if (y <= k) {
        return y;
    }
    float x = (y - k) / (1.0 - k);
    float w = (u_highlight_max - k) / (1.0 - k);
    return k + (1.0 - k) * min(x * (1.0 + x / (w * w)) / (1.0 + x), 1.0);
}

float srgb_encode(float x) {
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

float gog_inverse(float l, vec4 p) {
    // d = (l^(1/γ) − offset) / gain
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

// Absolute XYZ (Y in cd·m⁻²) → (linear RGB before clipping, relative luminance y).
vec4 display_linear(vec3 xyz_abs) {
    return u_display_linear * vec4(xyz_abs, 1.0);
}

// (linear RGB, y) of display_linear → (drive values 0..1, out-of-gamut excess ≥ 0).
vec4 display_drive_linear(vec4 lin_y) {
#if HIGHLIGHT_ROLLOFF == 1
    {
        // a glint above the display's white: its luminance rolled off, its chromaticity kept
        // (display XYZ − offset scaled by y'/y: linear RGB and y scale alike)
        float y = lin_y.w;
        if (y > u_highlight_knee) {
            lin_y *= highlight_rolloff(y) / y;
        }
    }
#endif
    vec3 lin = lin_y.rgb;
    float excess = max(max(max(-lin.r, -lin.g), -lin.b), max(max(lin.r, lin.g), lin.b) - 1.0);
#if GAMUT_MAPPING == 1
    if (excess > 1e-6) {
        // chroma mapping: toward the grey of the same luminance until every channel fits
        float g = clamp(lin_y.w, 0.0, 1.0);
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
    return vec4(clamp(d, 0.0, 1.0), max(excess, 0.0));
}

// Absolute XYZ (Y in cd·m⁻²) → (drive values 0..1, out-of-gamut excess ≥ 0).
vec4 display_drive(vec3 xyz_abs) {
    return display_drive_linear(display_linear(xyz_abs));
}
