// A full-screen post pass's stage: its body (common/<pass>.glsl) runs as a fragment shader
// (<pass>.frag: main() calls PostMain(), the outputs are colour attachments) or as a compute
// shader (<pass>.comp: TESSERA_COMPUTE; 8x8 pixels per workgroup, the outputs are globals that
// main() stores into storage images after PostMain()). FRAG_COORD is the pixel's centre in
// framebuffer pixels in both.
#ifndef TESSERA_POST_IO_GLSL
#define TESSERA_POST_IO_GLSL
// POST_IO(name) declares the pixel centre in uv (v_uv) and the one output, `name`: a fragment shader's
// input and colour attachment, or globals the compute wrapper sets and stores.
#ifdef TESSERA_COMPUTE
layout(local_size_x = 8, local_size_y = 8) in;
#define FRAG_COORD (vec2(gl_GlobalInvocationID.xy) + 0.5)
#define POST_IO(name) \
  vec2 v_uv;          \
  vec4 name;
#else
#define FRAG_COORD gl_FragCoord.xy
#define POST_IO(name)                \
  layout(location = 0) in vec2 v_uv; \
  layout(location = 0) out vec4 name;
#endif
#endif
