// vis_mlaa's blend list (common/vis_resolve.glsl): the edge list entries whose pixel has more
// than one surface (a runner-up), which the runner-up steps and geometric AA run over. Its
// indices follow the edge list in the pixel lists, and it is counted (and dispatched) in the
// entry after the edge list's. Needs `entries` (GpuShadeEntry[]) and `pixels` (uint[]) declared
// first.
#ifndef TESSERA_BLEND_LIST_GLSL
#define TESSERA_BLEND_LIST_GLSL

// The blend list's entry: the one after the edge list's, `edges`.
uint BlendListCounter(uint edges) { return edges + 1u; }
// Where the blend list starts in the pixel lists: after the edge list.
uint BlendListStart(uint edges) { return entries[edges].dispatch.w; }
// Its length.
uint BlendListLength(uint edges) { return entries[BlendListCounter(edges)].dispatch.w; }

// The invocation's blend list entry, one per invocation of a dispatch over it (kShadeGroupSize
// to a workgroup, as the resolve's args step sized it): the edge list entry it names, or false
// past the list's end.
bool BlendListEntry(uint edges, out uint entry) {
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint k = group * kShadeGroupSize + gl_LocalInvocationIndex;
  entry = 0u;
  if (k >= BlendListLength(edges)) return false;
  entry = pixels[BlendListStart(edges) + k];
  return true;
}
#endif
