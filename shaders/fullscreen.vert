#version 460
// One triangle that covers the screen (vertices 0..2, no vertex buffer).
layout(location = 0) out vec2 v_uv;

void main() {
  v_uv = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);
  gl_Position = vec4(v_uv * 2.0 - 1.0, 0.0, 1.0);
}
