#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// Image-based lighting, step 1: renders the procedural sky (common/ibl_sky.glsl) into mip 0 of
// the environment cube map, one invocation per texel, gl_GlobalInvocationID.z = face (0..5 =
// +X, -X, +Y, -Y, +Z, -Z). The cube is written as a 6-layer image2DArray view; each texel holds
// the sky along the direction through its centre (common/cube.glsl), so a samplerCube lookup
// of the finished map returns it. The mip chain is then made with blits, and the irradiance
// (ibl_irradiance.comp) and prefiltered specular (ibl_specular.comp) maps are built from it.
#include "common/cube.glsl"
#include "common/ibl_sky.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(set = 0, binding = 0, rgba16f) uniform writeonly image2DArray u_env;
layout(push_constant) uniform Push { TS_PUSH_IBL_ENV } push;  // common/gpu_types.h

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint size = push.size.x;
  if (id.x >= size || id.y >= size || id.z >= 6u) return;
  vec3 dir = CubeDirection(id.z, (vec2(id.xy) + 0.5) / float(size));
  vec3 color = ProceduralSky(dir, push.sun_dir.xyz, push.sun_color.rgb, push.zenith.rgb,
                             push.horizon.rgb, push.ground.rgb);
  imageStore(u_env, ivec3(id), vec4(color, 1.0));
}
