// The visibility shading's counters (vis_classify.glsl, vis_resolve.comp): Append adds this
// invocation's pixel to one of a material's counters (its count, its fill cursor, the sky's
// background count), one atomic per subgroup and material
// with SHADE_APPEND_SUBGROUPS (WaveMatch by peeling: the lanes of the first lane's material take
// their ranks from a ballot), else one per invocation; DispatchFor sizes a dispatch over a list.
// Needs `entries` (GpuShadeEntry[], read-write) declared first.
#ifndef TESSERA_SHADE_APPEND_GLSL
#define TESSERA_SHADE_APPEND_GLSL
// The indirect dispatch (VkDispatchIndirectCommand) over a list of `invocations` entries,
// kShadeGroupSize to a workgroup, at most kShadeDispatchWidth workgroups wide (more rows above).
uvec3 DispatchFor(uint invocations) {
  uint groups = (invocations + kShadeGroupSize - 1u) / kShadeGroupSize;
  uint width = min(groups, kShadeDispatchWidth);
  return uvec3(width, width == 0u ? 0u : (groups + width - 1u) / width, 1u);
}

// The counters of an entry Append adds to.
const uint kCountPixels = 0u;      // GpuShadeEntry.dispatch.w: the pixels counted for the list
const uint kCountCursor = 1u;      // list.y: the fill cursor
const uint kCountBackground = 2u;  // list.z (the sky's entry): the pixels the sky was written at

// Adds n to counter `counter` (kCount*) of material m's entry; returns the value before.
uint Add(uint m, uint counter, uint n) {
  return counter == kCountPixels   ? atomicAdd(entries[m].dispatch.w, n)
         : counter == kCountCursor ? atomicAdd(entries[m].list.y, n)
                                   : atomicAdd(entries[m].list.z, n);
}

// Adds 1 for this invocation to counter `counter` (a literal, kCount*) of material m's entry and
// returns the value before this invocation's add.
uint Append(uint m, uint counter) {
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
        base = Add(m, counter, n);
      }
      slot = subgroupBroadcastFirst(base) + subgroupBallotExclusiveBitCount(same);
      done = true;
    }
  }
  return slot;
#else
  return Add(m, counter, 1u);
#endif
}
#endif
