#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// vis_mlaa shading: one full-screen triangle per material at that material's depth; the
// EQUAL test against the material-depth target leaves the material's pixels (the scissor is
// the rectangle its drawables can cover).
layout(push_constant) uniform Push { TS_PUSH_VIS_SHADE } push;  // common/gpu_types.h
layout(location = 0) out vec2 v_uv;

void main() {
  v_uv = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);
  gl_Position = vec4(v_uv * 2.0 - 1.0, push.depth, 1.0);
}
