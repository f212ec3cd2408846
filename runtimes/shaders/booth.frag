#version 300 es
// Diffuse booth surfaces: spectral radiance L_b = ρ_b · E_b / π per band, as four vec4
// blocks (band 4k + c in channel c of block k), written to four RGBA32F targets (the
// analysis and deferred schedules).
//
// SHADE_TO_DISPLAY 1 (the realtime schedule; include: lib_display.glsl, lib_dither.glsl):
// the vertex shader has already taken the bands to XYZ and through the display model's affine
// part (surface.vert with VERTEX_XYZ 1); the rest of the display model and the dither finish
// the pixel here and the 8-bit colour is written.
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef SHADE_TO_DISPLAY
#define SHADE_TO_DISPLAY 0
#endif

#if SHADE_TO_DISPLAY
in vec4 v_linear;

layout(location = 0) out vec4 o_rgba;

void main() {
    o_rgba = vec4(dither8(display_drive_linear(v_linear).rgb, ivec2(gl_FragCoord.xy)), 1.0);
}

#else
flat in int v_material;
in vec4 v_irradiance0;
in vec4 v_irradiance1;
in vec4 v_irradiance2;
in vec4 v_irradiance3;

// Band reflectances for this lighting: row = material index, texel k = bands 4k..4k+3.
uniform sampler2D u_materials;

layout(location = 0) out vec4 o_radiance0;
layout(location = 1) out vec4 o_radiance1;
layout(location = 2) out vec4 o_radiance2;
layout(location = 3) out vec4 o_radiance3;

const float INV_PI = 0.31830988618379067;

void main() {
    int m = v_material;
    o_radiance0 = texelFetch(u_materials, ivec2(0, m), 0) * v_irradiance0 * INV_PI;
    o_radiance1 = texelFetch(u_materials, ivec2(1, m), 0) * v_irradiance1 * INV_PI;
    o_radiance2 = texelFetch(u_materials, ivec2(2, m), 0) * v_irradiance2 * INV_PI;
    o_radiance3 = texelFetch(u_materials, ivec2(3, m), 0) * v_irradiance3 * INV_PI;
}
#endif
