#version 460
#extension GL_GOOGLE_include_directive : require
// Skinning and morphing of the deformed drawables' vertices (renderer/features/skinning.cpp),
// every drawable in one dispatch: each workgroup finds its drawable's job by its first workgroup.
// glTF 3.7.2 and 3.7.3: the rest vertex plus each morph target's delta times its weight, then, when skinned,
// the weighted sum of its joints' matrices applied (position, normal and tangent), giving
// world-space vertices. renderer/scene/animation.h's MorphPosition and SkinPoint are the CPU
// reference the tests hold this to.
#include "common/gpu_types.h"

layout(local_size_x = kSkinGroupSize) in;

layout(set = 0, binding = kSkinBindingVertices, std430) buffer VertexBlock { float vertices[]; };
layout(set = 0, binding = kSkinBindingAttributes, std430) readonly buffer AttributeBlock {
  uvec4 attributes[];  // per vertex: joints, then weights (float bits)
};
layout(set = 0, binding = kSkinBindingDeltas, std430) readonly buffer DeltaBlock { float deltas[]; };
layout(set = 0, binding = kSkinBindingPose, std430) readonly buffer PoseBlock { float pose[]; };
struct SkinJob {
  uvec4 range;
  uvec4 pose;
  uvec4 groups;
};
layout(set = 0, binding = kSkinBindingJobs, std430) readonly buffer JobBlock { SkinJob jobs[]; };
layout(push_constant) uniform Push { TS_PUSH_SKIN } push;  // common/gpu_types.h

mat4 Joint(uint base, uint j) {
  uint b = (base + j) * 16u;
  return mat4(pose[b + 0u], pose[b + 1u], pose[b + 2u], pose[b + 3u],
              pose[b + 4u], pose[b + 5u], pose[b + 6u], pose[b + 7u],
              pose[b + 8u], pose[b + 9u], pose[b + 10u], pose[b + 11u],
              pose[b + 12u], pose[b + 13u], pose[b + 14u], pose[b + 15u]);
}

vec3 Load3(uint b) { return vec3(vertices[b], vertices[b + 1u], vertices[b + 2u]); }
vec3 Delta3(uint b) { return vec3(deltas[b], deltas[b + 1u], deltas[b + 2u]); }

// Vertex v of the job (0-based) deformed: the rest vertex plus the morph targets' deltas at their
// weights (target t's delta for vertex v is delta first + t * count + v), then skinned.
struct Deformed {
  vec3 position;
  vec3 normal;
  vec3 tangent;
};
Deformed Deform(uvec4 range, uvec4 job_pose, uint v, bool directions) {
  uint src = (range.x + v) * kVertexFloats;
  Deformed o;
  o.position = Load3(src);
  o.normal = directions ? Load3(src + 3u) : vec3(0.0);
  o.tangent = directions ? Load3(src + 6u) : vec3(0.0);
  for (uint t = 0u; t < job_pose.z; ++t) {
    float w = pose[job_pose.y + t];
    if (w == 0.0) continue;
    uint d = (job_pose.w + t * range.z + v) * kMorphDeltaFloats;
    o.position += w * Delta3(d);
    if (directions) {
      o.normal += w * Delta3(d + 3u);
      o.tangent += w * Delta3(d + 6u);
    }
  }
  if ((range.w & kSkinJobSkinned) != 0u) {
    uvec4 joints = attributes[(range.x + v) * 2u];
    vec4 weights = uintBitsToFloat(attributes[(range.x + v) * 2u + 1u]);
    // Only the joints that weigh: an unused slot's index need not name a joint of the skin.
    mat4 m = mat4(0.0);
    for (int k = 0; k < 4; ++k)
      if (weights[k] != 0.0) m += weights[k] * Joint(job_pose.x, joints[k]);
    o.position = (m * vec4(o.position, 1.0)).xyz;
    // The blended matrix's linear part for directions, as three.js and Filament do (exact for
    // rigid and uniformly scaled joints).
    o.normal = mat3(m) * o.normal;
    o.tangent = mat3(m) * o.tangent;
  }
  return o;
}

void main() {
  // The last job whose first workgroup is at or before this one (jobs are in workgroup order).
  uint group = gl_WorkGroupID.x + push.jobs.y;
  uint lo = 0u, hi = push.jobs.x - 1u;
  while (lo < hi) {
    uint mid = (lo + hi + 1u) / 2u;
    if (jobs[mid].groups.x <= group) lo = mid; else hi = mid - 1u;
  }
  uvec4 range = jobs[lo].range;
  uvec4 job_pose = jobs[lo].pose;
  uint v = (group - jobs[lo].groups.x) * kSkinGroupSize + gl_LocalInvocationID.x;
  if (v >= range.z) return;
  uint src = (range.x + v) * kVertexFloats;
  uint dst = (range.y + v) * kVertexFloats;
  Deformed d = Deform(range, job_pose, v, true);
  vec3 normal = d.normal;
  if ((range.w & kSkinJobFlat) != 0u) {
    // Flat shading (the file gave no normals): the deformed face's normal, from its three
    // corners (vertices 3t, 3t + 1, 3t + 2), as the importer computed it at rest.
    uint first = v - v % 3u;
    vec3 p0 = first == v ? d.position : Deform(range, job_pose, first, false).position;
    vec3 p1 = first + 1u == v ? d.position : Deform(range, job_pose, first + 1u, false).position;
    vec3 p2 = first + 2u == v ? d.position : Deform(range, job_pose, first + 2u, false).position;
    normal = cross(p1 - p0, p2 - p0);
  }
  float nl = length(normal);
  normal = nl > 0.0 ? normal / nl : vec3(0.0, 0.0, 1.0);
  float tl = length(d.tangent);
  vec3 tangent = tl > 0.0 ? d.tangent / tl : vec3(1.0, 0.0, 0.0);

  vertices[dst + 0u] = d.position.x;
  vertices[dst + 1u] = d.position.y;
  vertices[dst + 2u] = d.position.z;
  vertices[dst + 3u] = normal.x;
  vertices[dst + 4u] = normal.y;
  vertices[dst + 5u] = normal.z;
  vertices[dst + 6u] = tangent.x;
  vertices[dst + 7u] = tangent.y;
  vertices[dst + 8u] = tangent.z;
  vertices[dst + 9u] = vertices[src + 9u];  // the bitangent sign
  for (uint k = 10u; k < kVertexFloats; ++k) vertices[dst + k] = vertices[src + k];  // uvs, colour
}
