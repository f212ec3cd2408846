#version 300 es
// Display model (the analysis schedule): absolute XYZ → drive values; alpha = out-of-gamut
// excess (include: lib_display.glsl, which documents the model).
precision highp float;
precision highp int;
precision highp sampler2D;

uniform sampler2D u_xyz;

layout(location = 0) out vec4 o_drive;

void main() {
    o_drive = display_drive(texelFetch(u_xyz, ivec2(gl_FragCoord.xy), 0).xyz);
}
