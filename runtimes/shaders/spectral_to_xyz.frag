#version 300 es
// Spectral → XYZ (the analysis schedule): XYZ = Σ_k W_k · L_k over the four band blocks
// (include: lib_spectral.glsl).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_radiance0;
uniform sampler2D u_radiance1;
uniform sampler2D u_radiance2;
uniform sampler2D u_radiance3;

layout(location = 0) out vec4 o_xyz;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    o_xyz = vec4(spectral_to_xyz(texelFetch(u_radiance0, p, 0), texelFetch(u_radiance1, p, 0),
                                 texelFetch(u_radiance2, p, 0), texelFetch(u_radiance3, p, 0)), 1.0);
}
