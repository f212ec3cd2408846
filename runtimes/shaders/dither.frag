#version 300 es
// Spatial dithering before 8-bit quantisation: q = floor(255·d + n) / 255 with a
// blue-noise threshold n in [0, 1) tiled over the image (amplitude 0: n = 0.5,
// plain rounding).  Channels G and B read the mask at offsets (size/2, size/3) and
// (size/3, size/2) so the channels' errors are not correlated.
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_drive;
uniform sampler2D u_noise;           // (size × size), thresholds in [0, 1) in .r (and .gba)
uniform int u_noise_size;          // a power of two
uniform ivec4 u_noise_offsets;      // (x, y) offsets of channels G and B
uniform float u_dither_amplitude;

layout(location = 0) out vec4 o_rgba;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 d = texelFetch(u_drive, p, 0).rgb;
    // tile the mask: & (size − 1) is the modulo for a power-of-two size (integer division
    // is not vectorised on CPUs and dominated this pass on llvmpipe)
    int m = u_noise_size - 1;
    vec3 n = vec3(texelFetch(u_noise, p & m, 0).r,
                  texelFetch(u_noise, (p + u_noise_offsets.xy) & m, 0).r,
                  texelFetch(u_noise, (p + u_noise_offsets.zw) & m, 0).r);
    n = mix(vec3(0.5), n, u_dither_amplitude);
    vec3 q = clamp(floor(d * 255.0 + n), 0.0, 255.0) / 255.0;
    o_rgba = vec4(q, 1.0);
}
