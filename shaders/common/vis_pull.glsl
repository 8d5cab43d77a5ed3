// The visibility pass's vertex shaders with pulled vertices (DeviceInfo::vertex_pulling): each
// draw is non-indexed over its drawable's range of the index buffer (firstVertex = the range's
// first index, firstInstance = the drawable: the draw command's pulled half, pass.h
// DrawCommand), and the shader reads the index and the vertex itself (vis.glsl, in the pass's
// set kVisSet). It passes on the sample's id (drawable and triangle within it) as one flat
// value, where the indexed draws' fragment shaders read the triangle as gl_PrimitiveID: for that
// llvmpipe assembles every triangle's vertices again on its single-threaded front end, whose
// set-up also pays per flat value (the drawable and the triangle passed apart made Sponza's
// 4-sample pass about 9% slower). Sponza at 1280x720 on lavapipe: the visibility pass at 4
// samples 101-110 -> 91-99 ms, at one 53-63 -> 45-48 ms (README, "The visibility pipeline").
// Only gl_PrimitiveID's cost goes: the depth prepass drawn this way took as long as indexed
// (32-35 ms both). A GPU's post-transform cache shades a shared vertex once, so GPUs draw
// indexed. With VIS_PULL_UVS (the alpha-mask geometry's shader) it passes the uvs on too, for
// the alpha test.
#include "common/scene.glsl"
#include "common/vis.glsl"

// The drawable's world matrix and ids (GpuDrawable), fetched per instance: the same for every
// vertex of the draw, where the texel view would be read again for each.
layout(location = kAttrDrawableWorld) in vec4 in_world[4];
layout(location = kAttrDrawableIds) in uvec4 in_ids;

layout(location = 5) flat out uint v_id;
#ifdef VIS_PULL_UVS
layout(location = 3) out vec2 v_uv0;
layout(location = 4) out vec2 v_uv1;
layout(location = 6) out vec4 v_color;  // COLOR_0, whose alpha the mask cuts out too
#endif

void main() {
  uint k = uint(gl_VertexIndex);  // the place in the index buffer
  uint v = IndexedVertex(in_ids, k);
  // The same arithmetic on the same bits as the indexed draws' attribute: the same pixels.
  gl_Position = ClipPosition(mat4(in_world[0], in_world[1], in_world[2], in_world[3]),
                             VertexPosition(v));
  // vis.glsl's id; the triangle is the same for its three vertices.
  v_id = ((uint(gl_InstanceIndex) + 1u) << frame.aa.x) | ((k - in_ids.z) / 3u);
#ifdef VIS_PULL_UVS
  vec4 uv = VertexUvs(v);
  v_uv0 = uv.xy;
  v_uv1 = uv.zw;
  v_color = VertexColor(v);
#endif
}
