#version 300 es
// The deferred schedule's full-screen pass: spectral → XYZ → display → dither → 8 bit from
// the four spectral images (include: lib_spectral.glsl, lib_display.glsl, lib_dither.glsl,
// the very functions the analysis schedule runs one pass at a time).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_radiance0;
uniform sampler2D u_radiance1;
uniform sampler2D u_radiance2;
uniform sampler2D u_radiance3;

layout(location = 0) out vec4 o_rgba;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 xyz = spectral_to_xyz(texelFetch(u_radiance0, p, 0), texelFetch(u_radiance1, p, 0),
                               texelFetch(u_radiance2, p, 0), texelFetch(u_radiance3, p, 0));
    o_rgba = vec4(dither8(display_drive(xyz).rgb, p), 1.0);
}
