#version 300 es
// Diffuse booth surfaces: spectral radiance L_b = ρ_b · E_b / π per band, written as
// four RGBA32F blocks (band 4k + c in channel c of block k).
precision highp float;
precision highp int;
precision highp sampler2D;

in vec3 v_position_mm;
in vec3 v_normal;
in vec2 v_uv;
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
