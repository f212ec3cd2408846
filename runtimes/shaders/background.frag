#version 300 es
// The realtime schedule's background: pixels no surface covers show zero radiance through
// the display model and the dither, exactly as the analysis schedule shows them (drawn last,
// at the far plane, where the depth buffer is still clear; include: lib_display.glsl,
// lib_dither.glsl).
precision highp float;
precision highp int;
precision highp sampler2D;

layout(location = 0) out vec4 o_rgba;

void main() {
    o_rgba = vec4(dither8(display_drive(vec3(0.0)).rgb, ivec2(gl_FragCoord.xy)), 1.0);
}
