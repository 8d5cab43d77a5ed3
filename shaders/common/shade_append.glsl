// The visibility shading's counters (vis_classify.glsl, vis_resolve.comp): Append adds this
// invocation's pixel to a material's count or fill cursor, one atomic per subgroup and material
// with SHADE_APPEND_SUBGROUPS (WaveMatch by peeling: the lanes of the first lane's material take
// their ranks from a ballot), else one per invocation. Needs `entries` (GpuShadeEntry[],
// read-write) declared first.
#ifndef TESSERA_SHADE_APPEND_GLSL
#define TESSERA_SHADE_APPEND_GLSL
// Adds `n` = 1 for this invocation to counter `word` of material m's entry (0: the pixel
// count, 1: the fill cursor) and returns the value before this invocation's add.
uint Append(uint m, bool cursor) {
#ifdef SHADE_APPEND_SUBGROUPS
  uint slot = 0u;
  bool done = false;
  while (!done) {
    uint first = subgroupBroadcastFirst(m);
    if (m == first) {
      uvec4 same = subgroupBallot(true);
      uint n = subgroupBallotBitCount(same);
      uint base = 0u;
      if (subgroupElect()) {
        base = cursor ? atomicAdd(entries[m].list.y, n) : atomicAdd(entries[m].dispatch.w, n);
      }
      slot = subgroupBroadcastFirst(base) + subgroupBallotExclusiveBitCount(same);
      done = true;
    }
  }
  return slot;
#else
  return cursor ? atomicAdd(entries[m].list.y, 1u) : atomicAdd(entries[m].dispatch.w, 1u);
#endif
}
#endif
