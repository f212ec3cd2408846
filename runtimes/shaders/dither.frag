#version 300 es
// Spatial dithering, then quantisation to 8 bits (the analysis schedule; include:
// lib_dither.glsl).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_drive;

layout(location = 0) out vec4 o_rgba;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    o_rgba = vec4(dither8(texelFetch(u_drive, p, 0).rgb, p), 1.0);
}
