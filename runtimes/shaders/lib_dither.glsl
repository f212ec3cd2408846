// lbscene shader library (a GLSL ES 3.00 chunk without #version): spatial dithering before
// 8-bit quantisation: q = floor(255·d + n) / 255 with a blue-noise threshold n in [0, 1)
// tiled over the image (amplitude 0: n = 0.5, plain rounding).  Channels G and B use the
// mask shifted by (size/2, size/3) and (size/3, size/2) so the channels' errors are not
// correlated; the shifted masks are stored in the texture's G and B channels (one texel
// fetch per pixel instead of three: fetches dominate this function on llvmpipe).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_noise;           // (size × size): thresholds in [0, 1) of channels R, G, B
uniform int u_noise_size;            // a power of two
uniform float u_dither_amplitude;

// Drive values 0..1 at pixel p → quantised values k/255.
vec3 dither8(vec3 d, ivec2 p) {
    // tile the mask: & (size − 1) is the modulo for a power-of-two size (integer division
    // is not vectorised on CPUs and dominated this pass on llvmpipe)
    vec3 n = texelFetch(u_noise, p & (u_noise_size - 1), 0).rgb;
    n = mix(vec3(0.5), n, u_dither_amplitude);
    return clamp(floor(d * 255.0 + n), 0.0, 255.0) / 255.0;
}
