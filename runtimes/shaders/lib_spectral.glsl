// lbscene shader library (a GLSL ES 3.00 chunk without #version): spectral → XYZ.
// The runtime puts chunks named in a program's "include" list after the #version line and
// the #define lines, in order (plain string concatenation, as a WebGL2 runtime would do).
//   XYZ = Σ_k W_k · L_k over the four band blocks, where column c of W_k holds the XYZ
//   weights of band 4k + c (Y in cd·m⁻² per W·sr⁻¹·m⁻²·nm⁻¹, for the light at the sample).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform mat4x3 u_xyz_weights[4];

vec3 spectral_to_xyz(vec4 l0, vec4 l1, vec4 l2, vec4 l3) {
    return u_xyz_weights[0] * l0 + u_xyz_weights[1] * l1 + u_xyz_weights[2] * l2 + u_xyz_weights[3] * l3;
}
