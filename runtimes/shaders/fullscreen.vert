#version 300 es
// One triangle covering the viewport, from gl_VertexID alone (no vertex buffer), at clip
// depth FULLSCREEN_Z (0: mid-range; 1: the far plane, for backgrounds drawn last).
precision highp float;

#ifndef FULLSCREEN_Z
#define FULLSCREEN_Z 0.0
#endif

const vec2 CORNERS[3] = vec2[3](vec2(-1.0, -1.0), vec2(3.0, -1.0), vec2(-1.0, 3.0));

void main() {
    gl_Position = vec4(CORNERS[gl_VertexID], FULLSCREEN_Z, 1.0);
}
