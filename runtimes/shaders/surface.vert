#version 300 es
// Booth surfaces and the sample: booth millimetres → clip space.  Carries the
// band irradiance of the vertex (16 bands as 4 vec4 blocks, W·m⁻²·nm⁻¹) to the
// fragment shaders, which interpolate it across the triangle.
//
// VERTEX_XYZ 1 (the realtime schedule's diffuse booth surfaces; include: lib_spectral.glsl):
// the diffuse radiance ρ_b·E_b/π of the vertex's 16 bands is taken to XYZ here, and on through
// the display model's affine part (u_display_linear, lib_display.glsl: exposure, adaptation,
// offset, matrix to linear channel values, relative luminance), and that is interpolated
// instead.  Radiance, and so XYZ and any affine map of it, is linear in the irradiance and the
// material is constant over a triangle, so interpolating it gives the value of the
// interpolated bands: the same image for 4 varyings instead of 16, and two matrix products
// per vertex instead of per pixel.
//
// COATING 1 (the sample draw of an effect coating; vertex_include: lib_coating.glsl): the
// v_irradiance blocks carry the coating's smooth radiance (W·sr⁻¹·m⁻²·nm⁻¹) instead, with the
// glint parameters per emitter and the diffuse share for sample.frag.
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef VERTEX_XYZ
#define VERTEX_XYZ 0
#endif
#ifndef COATING
#define COATING 0
#endif

in vec3 a_position_mm;
in vec3 a_normal;
in vec2 a_uv;
in float a_material;
in vec4 a_irradiance0;
in vec4 a_irradiance1;
in vec4 a_irradiance2;
in vec4 a_irradiance3;

uniform mat4 u_view_proj;
uniform mat4 u_model;   // rigid transform (identity when geometry is placed on the CPU)

#if VERTEX_XYZ
uniform sampler2D u_materials;   // row = material index, texel k = bands 4k..4k+3
uniform mat4 u_display_linear;   // (XYZ, 1) → (linear channel values, y): lib_display.glsl
out vec4 v_linear;
#else
out vec3 v_position_mm;
out vec3 v_normal;
out vec2 v_uv;
flat out int v_material;
out vec4 v_irradiance0;
out vec4 v_irradiance1;
out vec4 v_irradiance2;
out vec4 v_irradiance3;
#endif
#if COATING
uniform vec3 u_sample_u_axis;    // the sample's u axis, placed for the view (before u_model)
out vec4 v_glint0;
out vec4 v_glint1;
out vec4 v_glint2;
out vec4 v_glint3;
out float v_diffuse_share;
#endif

void main() {
    vec4 p = u_model * vec4(a_position_mm, 1.0);
#if VERTEX_XYZ
    int m = int(a_material + 0.5);
    const float INV_PI = 0.31830988618379067;
    vec3 xyz = spectral_to_xyz(texelFetch(u_materials, ivec2(0, m), 0) * a_irradiance0 * INV_PI,
                               texelFetch(u_materials, ivec2(1, m), 0) * a_irradiance1 * INV_PI,
                               texelFetch(u_materials, ivec2(2, m), 0) * a_irradiance2 * INV_PI,
                               texelFetch(u_materials, ivec2(3, m), 0) * a_irradiance3 * INV_PI);
    v_linear = u_display_linear * vec4(xyz, 1.0);
#else
    v_position_mm = p.xyz;
    v_normal = mat3(u_model) * a_normal;
    v_uv = a_uv;
    v_material = int(a_material + 0.5);
    v_irradiance0 = a_irradiance0;
    v_irradiance1 = a_irradiance1;
    v_irradiance2 = a_irradiance2;
    v_irradiance3 = a_irradiance3;
#if COATING
    vec3 n = normalize(v_normal);
    vec3 t1 = mat3(u_model) * u_sample_u_axis;
    t1 = normalize(t1 - n * dot(t1, n));
    coating_vertex(p.xyz, n, t1, a_irradiance0, a_irradiance1, a_irradiance2, a_irradiance3,
                   v_irradiance0, v_irradiance1, v_irradiance2, v_irradiance3, v_diffuse_share,
                   v_glint0, v_glint1, v_glint2, v_glint3);
#endif
#endif
    gl_Position = u_view_proj * p;
}
