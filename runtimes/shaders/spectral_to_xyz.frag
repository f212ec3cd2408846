#version 300 es
// Spectral → XYZ: XYZ = Σ_k W_k · L_k over the four band blocks, where column c of
// W_k holds the XYZ weights of band 4k + c (Y in cd·m⁻² per W·sr⁻¹·m⁻²·nm⁻¹).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_radiance0;
uniform sampler2D u_radiance1;
uniform sampler2D u_radiance2;
uniform sampler2D u_radiance3;
uniform mat4x3 u_xyz_weights[4];

layout(location = 0) out vec4 o_xyz;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 xyz = u_xyz_weights[0] * texelFetch(u_radiance0, p, 0)
             + u_xyz_weights[1] * texelFetch(u_radiance1, p, 0)
             + u_xyz_weights[2] * texelFetch(u_radiance2, p, 0)
             + u_xyz_weights[3] * texelFetch(u_radiance3, p, 0);
    o_xyz = vec4(xyz, 1.0);
}
