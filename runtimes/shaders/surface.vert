#version 300 es
// Booth surfaces and the sample: booth millimetres → clip space.  Carries the
// band irradiance of the vertex (16 bands as 4 vec4 blocks, W·m⁻²·nm⁻¹) to the
// fragment shaders, which interpolate it across the triangle.
precision highp float;
precision highp int;

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

out vec3 v_position_mm;
out vec3 v_normal;
out vec2 v_uv;
flat out int v_material;
out vec4 v_irradiance0;
out vec4 v_irradiance1;
out vec4 v_irradiance2;
out vec4 v_irradiance3;

void main() {
    vec4 p = u_model * vec4(a_position_mm, 1.0);
    v_position_mm = p.xyz;
    v_normal = mat3(u_model) * a_normal;
    v_uv = a_uv;
    v_material = int(a_material + 0.5);
    v_irradiance0 = a_irradiance0;
    v_irradiance1 = a_irradiance1;
    v_irradiance2 = a_irradiance2;
    v_irradiance3 = a_irradiance3;
    gl_Position = u_view_proj * p;
}
