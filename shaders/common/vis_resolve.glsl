// vis_mlaa resolve: groups a pixel's visibility samples by surface and picks the surface to
// shade. The samples are the multisampled visibility buffer's, or with VIS_RESOLVE_ANALYTIC
// (vis_mlaa_coverage analytic: vis_resolve_analytic.comp) found from a one-sample buffer by
// testing each sample position against the triangles nearby pixels show and their neighbours
// (AnalyticSamples). Two samples are on one surface when they hit the same triangle, or
// triangles of the same drawable that share a vertex, counting as one the vertices at one
// position whose normals are within 8.1 degrees (dot > 0.99) and whose texture coordinates are
// the same where the material's textures read them (not a texture seam: SurfaceCorners), or
// joined through other samples.
// The surface owning the most samples wins (ties: the one holding the lowest sample). Writes, per pixel:
//  - u_id: the id of the winning sample nearest the mean position of the winning samples
//    (the triangle the shading intersects);
//  - u_coverage: the winning samples' mask and their mean position (PackCoverage).
// Only edge pixels (samples on more than one triangle; analytic: a 3x3 neighbourhood showing
// more than one surface) are grouped, so the cost comes from the edges: mode kResolveUniform
// writes every pixel whose samples agree and lists the others,
// kResolveArgs sizes the indirect dispatch over that list (and later over the blend list),
// kResolveEdges groups the listed
// pixels, every invocation one edge pixel (lavapipe runs masked-off lanes at full cost: as a
// full-screen fragment pass the grouping cost every 8-pixel block that held an edge pixel).
// The surface with the next most samples, the runner-up, is recorded whatever its share, down to
// one sample (u_runner_ups, one record per edge list entry), and the edge pixels that have one
// (more than one surface) are listed again, by their edge list index, in the blend list (the
// entry after the edge list's; its indices follow the edge list in the pixel lists): the others
// are edges between triangles of one surface (164,481 of Sponza's 215,261 at 1280x720), which
// geometric AA passes through, so the runner-ups' steps and geometric AA run over the blend
// list only (lavapipe runs every lane through the code of every branch, so returning early for
// the others saved nothing). kResolveRunnerUps then looks for the runner-up
// in the 8 neighbours' shaded ids, nearest in angle to where its samples lie first: geometric AA
// borrows its colour from the first that shows it, and where none does it is shaded here too (a
// wire or a gap thinner than a pixel otherwise vanishes wherever it loses the vote). Until
// 2026-11-28 only a runner-up holding 3/8 of the samples was recorded: with 4 samples a wire
// owning one of them vanished there (the edge scene's wire rows 137 -> 0 in 8-bit sRGB), which
// left its edge PSNR 1.25 dB below msaa's; now equal to it, for 0.4% more shading on Sponza.
// Every pixel's shaded surface (and every runner-up left to be shaded) is counted in its
// material's entry as it is decided (common/shade_append.glsl; a pixel whose surface is the sky
// is not: the classification, or the one-dispatch shading, writes the sky there; a runner-up that
// is the sky is, in the sky's entry), so the classification goes straight to its scan and lists
// (vis_classify_mlaa.comp), and the shading (vis_shade_mlaa.comp) shades each listed id. Where the
// shading is one dispatch over every pixel (DeviceInfo::shade_all_materials, vis_shade_all_mlaa.comp)
// there is no classification, and the counts are the frame's statistics. vis_resolve.comp counts one atomic per subgroup and material,
// vis_resolve_atomic.comp (devices without subgroup ballots) one per pixel.
#include "common/scene.glsl"
#include "common/vis.glsl"

layout(local_size_x = kShadeGroupSize) in;

layout(push_constant) uniform Push { TS_PUSH_SHADE } push;
#ifdef VIS_RESOLVE_ANALYTIC
layout(set = kVisSet, binding = kVisBindingSamples) uniform usampler2D u_vis;  // one sample
#else
layout(set = kVisSet, binding = kVisBindingSamples) uniform usampler2DMS u_vis;
#endif
layout(set = kVisSet, binding = kResolveBindingId, r32ui) uniform uimage2D u_id;
layout(set = kVisSet, binding = kResolveBindingCoverage, r32ui) uniform writeonly uimage2D u_coverage;
layout(set = kVisSet, binding = kShadeBindingEntries, std430) buffer EntryBlock {
  GpuShadeEntry entries[];
};
layout(set = kVisSet, binding = kShadeBindingPixels, std430) buffer PixelBlock {
  uint pixels[];
};
layout(set = kVisSet, binding = kShadeBindingRunnerUps, std430) buffer RunnerUpBlock {
  uvec2 runner_ups[];  // per edge list entry: the id to shade, PackRunnerUp (mask 0: none)
};
// Per index of the index buffer, the vertex standing for it in the surface test (SurfaceIndices,
// renderer/scene/adjacency.h), read as the indices are (vis.glsl's kVisTexels).
layout(set = kVisSet, binding = kResolveBindingSurfaces, std430) readonly buffer SurfaceBlock {
  uint surfaces[];
};
layout(set = kVisSet, binding = kResolveBindingSurfaceTexels) uniform usamplerBuffer
    surface_texels;
#include "common/shade_append.glsl"
#include "common/blend_list.glsl"

// The entry an id's pixels are counted in: its drawable's material's, or the sky's (the entry
// before the edge list's; runner-ups only).
uint MaterialOf(uint id, uint edges) {
  return id == 0u ? edges - 1u : DrawableIds(VisDrawable(id, frame.aa.x)).y;
}

// The sample count: a specialization constant (a pipeline per count), so the loops over samples
// unroll and the per-sample arrays below stay in registers (lavapipe keeps dynamically indexed
// local arrays in memory, which made the grouping most of vis_mlaa's frame).
layout(constant_id = 0) const uint kSamples = 4u;
// The mode (kResolve*): a specialization constant too, a pipeline per mode, so each dispatch's
// shader holds only its own code (lavapipe runs both sides of every branch under a lane mask:
// the uniform pass paid for the grouping's arithmetic on every pixel).
layout(constant_id = 1) const uint kMode = 0u;

// The vertices standing for visibility id `id`'s triangle's corners in the surface test
// (uvec3(0): the sky). SurfaceIndices (renderer/scene/adjacency.h) chose them on the CPU: of a
// primitive's vertices at one position (within 2^-21 of its size) with normals within 8.1 degrees (dot
// > 0.99) and the same texture coordinates in the sets the material's textures read (up to whole
// units where they repeat), the first. Across a texture seam (DamagedHelmet's visor rim against
// its shell) the two sides sample other texels, so they shade apart as two surfaces would; taken
// as one, the seam was shaded once and stayed aliased (tessera-aa-quality, lavapipe: the helmet's
// edge PSNR 27.23 -> 27.86 dB, msaa 28.09). Until 2026-11-28 the test compared the two
// triangles' vertex positions, normals and texture coordinates here, pair by pair: 36-40 ms of
// Sponza's 91-100 ms resolve on lavapipe (its full stack at 1280x720).
uvec3 SurfaceCorners(uint id) {
  if (id == 0u) return uvec3(0u);
  uint tb = frame.aa.x;
  uint first = DrawableIds(VisDrawable(id, tb)).z + 3u * VisTriangle(id, tb);
  if (kVisTexels) {
    return uvec3(texelFetch(surface_texels, int(first)).x,
                 texelFetch(surface_texels, int(first + 1u)).x,
                 texelFetch(surface_texels, int(first + 2u)).x);
  }
  return uvec3(surfaces[first], surfaces[first + 1u], surfaces[first + 2u]);
}

// Whether samples with ids a and b (their triangles' SurfaceCorners va, vb) are on one surface:
// the same triangle, or triangles of one drawable with a corner standing for the same vertex (so
// two triangles either side of a seam that ends at an unsplit vertex, sharing just that one, are
// one surface). Vector compares, no loops: a CPU device runs the lanes of a SIMD group together.
bool SameSurface(uint a, uint b, uvec3 va, uvec3 vb) {
  if (a == b) return true;
  uint tb = frame.aa.x;
  if (a == 0u || b == 0u || (a >> tb) != (b >> tb)) return false;
  return any(equal(uvec3(va.x), vb)) || any(equal(uvec3(va.y), vb)) || any(equal(uvec3(va.z), vb));
}

// The mean position of the samples in `mask`, and the id of the one nearest it.
void Pick(uint mask, uint ids[kSamples], out uint id, out vec2 mean) {
  mean = vec2(0.0);
  for (uint s = 0u; s < kSamples; ++s)
    if ((mask & (1u << s)) != 0u) mean += SamplePosition(kSamples, s);
  mean /= float(bitCount(mask));
  uint nearest = 0u;
  float nearest_d = 1e9;
  for (uint s = 0u; s < kSamples; ++s) {
    vec2 d = SamplePosition(kSamples, s) - mean;
    if ((mask & (1u << s)) != 0u && dot(d, d) < nearest_d) {
      nearest_d = dot(d, d);
      nearest = s;
    }
  }
  id = ids[0];
  for (uint s = 1u; s < kSamples; ++s)
    if (s == nearest) id = ids[s];
}

// The id whose triangle the shading intersects at `mean` (the pixel's fraction, as the coverage
// word or runner-up record quantized it): `id`, or where the camera ray through `mean` misses
// its triangle (a surface spanning several triangles), the first of the surface's other samples'
// triangles that holds it. One triangle per iteration of a loop, each id once: lavapipe runs a
// loop as many times as its busiest lane needs (at least once), where the four unrolled tests it
// replaced (one per sample, behind a branch) ran for every lane whatever the branch said.
// `firsts`: bit s set where sample s is the first of the pixel's samples with its id.
uint ContainingId(ivec2 p, uint mask, uint ids[kSamples], uint firsts, uint id, vec2 mean) {
  if (id == 0u) return 0u;
  // Bit s: sample s is the surface's first sample on a triangle other than `id`'s (samples with
  // one id are on one surface, so the first of them is in `mask` when any is).
  uint others = mask & firsts;
  for (uint s = 0u; s < kSamples; ++s)
    if (ids[s] == id) others &= ~(1u << s);
  vec3 dir = RayDirection(vec2(p) + mean);
  uint candidate = id;
  while (true) {
    Triangle tri = LoadTriangle(candidate);
    if (Inside(Barycentrics(tri.p0, tri.e1, tri.e2, dir))) return candidate;
    if (others == 0u) return id;
    uint next = uint(findLSB(others));
    others &= others - 1u;
    for (uint s = 0u; s < kSamples; ++s)
      if (s == next) candidate = ids[s];
  }
  return id;
}

#ifdef VIS_RESOLVE_ANALYTIC
// vis_mlaa_coverage analytic: the one-sample id of pixel p + d (the frame's border repeated
// outside it).
uint IdAt(ivec2 p, ivec2 d) {
  return texelFetch(u_vis, clamp(p + d, ivec2(0), ivec2(frame.counts.zw) - 1), 0).r;
}

layout(set = kVisSet, binding = kResolveBindingAdjacency, std430) readonly buffer AdjacencyBlock {
  uint adjacency[];  // per index: the triangle across the edge from that corner to the next
};

// Whether `tri` covers framebuffer point `at` (x: 1 or 0) and its depth there (y, reverse Z:
// larger is nearer), as the visibility pass's vertex shader and the rasterizer find them: edge
// functions in screen space, depth affine in screen space. Well conditioned for the thin
// triangles of a silhouette, where a ray's barycentrics lose their digits. A triangle reaching
// behind the camera (w <= 0 at a corner) is not tested: it shows at a pixel centre nearby.
float Edge(vec2 a, vec2 b, vec2 q) { return (b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x); }
struct ScreenTriangle {
  vec2 s0, s1, s2;
  vec3 z;       // depth at each corner
  float area;   // twice the signed area; 0: not testable
};
ScreenTriangle Project(Triangle tri) {
  vec4 c0 = frame.view_proj * vec4(tri.p0, 1.0);
  vec4 c1 = frame.view_proj * vec4(tri.p0 + tri.e1, 1.0);
  vec4 c2 = frame.view_proj * vec4(tri.p0 + tri.e2, 1.0);
  ScreenTriangle t;
  vec2 size = vec2(frame.counts.zw);
  t.s0 = (c0.xy / c0.w * 0.5 + 0.5) * size;
  t.s1 = (c1.xy / c1.w * 0.5 + 0.5) * size;
  t.s2 = (c2.xy / c2.w * 0.5 + 0.5) * size;
  t.z = vec3(c0.z / c0.w, c1.z / c1.w, c2.z / c2.w);
  t.area = min(c0.w, min(c1.w, c2.w)) > 0.0 ? Edge(t.s0, t.s1, t.s2) : 0.0;
  return t;
}
vec2 ScreenHit(ScreenTriangle t, vec2 at) {
  if (abs(t.area) < 1e-12) return vec2(0.0);
  vec3 b = vec3(Edge(t.s1, t.s2, at), Edge(t.s2, t.s0, at), Edge(t.s0, t.s1, at)) / t.area;
  return vec2(min(b.x, min(b.y, b.z)) >= -1e-5 ? 1.0 : 0.0, dot(b, t.z));
}

// Each sample's id: the nearest triangle covering the sample position among the triangles the
// 3x3 pixels around p show and the triangles one and two edges away from those (the thin
// triangles of a curved silhouette and the slivers of a fan, which no pixel centre shows, border
// the ones that are shown). A sample none of them covers sees the sky where the 3x3 shows it, else p's own id.
// An alpha-masked triangle's cut-outs are in its texture, which is not sampled here: it claims a
// sample only where p, or a pixel on the sample's side of p (across the nearer vertical,
// horizontal or diagonal edge), showed it (or the triangle it borders), that is where its alpha
// test passed nearby, and not at all where it lies in front of p's own surface at p's centre
// although p does not show it (p's centre is in one of its holes). A single-sided triangle
// facing away is skipped, as the rasterizer culls it. The distinct ids are gathered
// first (at most kCandidates), so each triangle is loaded and tested once: a CPU device runs
// its lanes together, and a loop over the pixels cost every lane the tests of every id any lane
// had not seen.
// The ids shown and the triangles next to them, then the triangles next to those (two steps
// across edges: the demo's vis_mlaa 35.5 dB from raster's against 34.1 with one).
const uint kRinged = 16u, kCandidates = 32u;
void AnalyticSamples(ivec2 p, out uint ids[kSamples]) {
  uint tb = frame.aa.x;
  uint own = IdAt(p, ivec2(0));
  // A pixel whose own triangle reaches behind the camera (not testable in screen space: a
  // large triangle close by) keeps it at every sample.
  ScreenTriangle own_screen;
  own_screen.area = 1.0;
  if (own != 0u) own_screen = Project(LoadTriangle(own));
  if (own_screen.area == 0.0) {
    for (uint s = 0u; s < kSamples; ++s) ids[s] = own;
    return;
  }
  uint candidates[kCandidates];
  uint where[kCandidates];  // bit k: the 3x3's pixel k (row-major) shows it (or the one it borders)
  uint count = 0u;
  bool sky = false;
  for (uint k = 0u; k < 9u; ++k) {
    uint id = IdAt(p, ivec2(int(k % 3u) - 1, int(k / 3u) - 1));
    sky = sky || id == 0u;
    bool seen = id == 0u;
    for (uint j = 0u; j < count; ++j) {
      if (candidates[j] == id) {
        seen = true;
        where[j] |= 1u << k;
      }
    }
    if (!seen) {
      candidates[count] = id;
      where[count++] = 1u << k;
    }
  }
  for (uint c = 0u; c < count && c < kRinged; ++c) {
    uint id = candidates[c];
    uint first = DrawableIds(VisDrawable(id, tb)).z + 3u * VisTriangle(id, tb);
    for (uint e = 0u; e < 3u; ++e) {
      uint t = adjacency[first + e];
      uint next = (id & ~((1u << tb) - 1u)) | t;
      // (A triangle reached again keeps the pixels it was first found from: merging them here
      // cost lavapipe the resolve twice over, for masked triangles' side rule only.)
      bool seen = t == 0xffffffffu;
      for (uint j = 0u; j < count; ++j) seen = seen || candidates[j] == next;
      if (!seen && count < kCandidates) {
        candidates[count] = next;
        where[count++] = where[c];
      }
    }
  }
  vec2 spots[kSamples];
  float nearest[kSamples];
  uint side[kSamples];  // the 3x3 pixels a masked triangle must show to claim the sample
  vec2 centre = vec2(p) + 0.5;
  float own_at_centre = own == 0u ? 0.0 : ScreenHit(own_screen, centre).y;
  for (uint s = 0u; s < kSamples; ++s) {
    vec2 at = SamplePosition(kSamples, s);
    spots[s] = vec2(p) + at;
    uint qx = at.x < 0.5 ? 0u : 2u, qy = at.y < 0.5 ? 0u : 6u;  // column, row * 3
    side[s] = (1u << 4u) | (1u << (3u + qx)) | (1u << (1u + qy)) | (1u << (qx + qy));
    ids[s] = 0xffffffffu;
    nearest[s] = -1.0;  // reverse Z: larger is nearer
  }
  for (uint j = 0u; j < count; ++j) {
    uint id = candidates[j];
    Triangle tri = LoadTriangle(id);
    ScreenTriangle st = Project(tri);
    uvec4 flags = materials[DrawableIds(tri.drawable).y].flags;  // x alpha mode, y double-sided
    // The visibility pass culls single-sided back faces (front: counter-clockwise in Vulkan's
    // framebuffer terms, a negative Edge area here); the walk across edges reaches them.
    if (flags.y == 0u && st.area > 0.0) continue;
    bool masked = id != own && flags.x == kAlphaMask;
    if (masked) {
      vec2 at_centre = ScreenHit(st, centre);
      if (at_centre.x > 0.0 && at_centre.y > own_at_centre) continue;
    }
    for (uint s = 0u; s < kSamples; ++s) {
      vec2 hit = ScreenHit(st, spots[s]);
      bool may = !masked || (where[j] & side[s]) != 0u;
      // Depth above 1 is in front of the near plane, which the rasterizer clips.
      if (may && hit.x > 0.0 && hit.y <= 1.0 && hit.y > nearest[s]) {
        nearest[s] = hit.y;
        ids[s] = id;
      }
    }
  }
  for (uint s = 0u; s < kSamples; ++s)
    if (ids[s] == 0xffffffffu) ids[s] = sky ? 0u : own;
}
#endif

#ifdef VIS_RESOLVE_ANALYTIC
// Whether every pixel of p's 3x3 shows p's own surface (its triangle, or one SameSurface joins
// to it directly): an edge pixel of the one-sample buffer inside a surface, where triangles of
// one mesh meet. Its samples then group into one surface, as a uniform pixel's do, unless one
// falls on a sliver of another surface that no pixel centre nearby shows; so it is written as a
// uniform pixel, by kResolveUniform, and not listed for the triangle tests. Sponza's atrium at
// 1280x720: 442,182 edge pixels -> 164,038, the resolve 1070 -> 535 ms on lavapipe, edge PSNR
// unchanged (tessera-aa-quality: Sponza 29.56 dB, helmet 27.00 -> 26.99, edge scene 15.85).
// Tested in the uniform pass, not at the start of the edge pass, so that the edge pass's lanes
// all run the triangle tests: there lavapipe's 8-lane groups skipped them only where all 8 lanes
// were inside a surface (the resolve 864 -> 719 ms, against 387 here, aa-quality's Sponza view).
bool OneSurfaceAround(ivec2 p) {
  uint own = IdAt(p, ivec2(0));
  if (own == 0u) return false;
  uvec3 ov = SurfaceCorners(own);
  bool one = true;
  for (uint k = 0u; k < 9u; ++k) {
    uint id = IdAt(p, ivec2(int(k % 3u) - 1, int(k / 3u) - 1));
    if (!one || id == own) continue;
    one = SameSurface(own, id, ov, SurfaceCorners(id));
  }
  return one;
}
#endif

// Groups the samples by surface (the transitive closure of SameSurface) and writes the outputs
// for the surface with the most samples (ties: the one holding the lowest sample), and edge list
// entry `entry`'s runner-up, listing the entry in the blend list where it has one. Returns the id
// to shade.
uint Group(ivec2 p, uint entry, uint edges, uint ids[kSamples]) {
  uvec3 tv[kSamples];  // each sample's SurfaceCorners
  for (uint s = 0u; s < kSamples; ++s) tv[s] = SurfaceCorners(ids[s]);
  uint same[kSamples];  // bit t of same[s]: sample t is on sample s's surface
  for (uint s = 0u; s < kSamples; ++s) same[s] = 1u << s;
  uint firsts = (1u << kSamples) - 1u;  // bit s: no earlier sample has sample s's id
  for (uint i = 0u; i < kSamples; ++i) {
    for (uint j = i + 1u; j < kSamples; ++j) {
      if (ids[i] == ids[j]) firsts &= ~(1u << j);
      if (SameSurface(ids[i], ids[j], tv[i], tv[j])) {
        same[i] |= 1u << j;
        same[j] |= 1u << i;
      }
    }
  }
  // The closure, Warshall's way: after step k, a sample's set holds every sample joined to it
  // through samples 0..k (kSamples^2 steps, where repeating a pass joining each set's members'
  // sets until nothing changes took kSamples^3).
  for (uint k = 0u; k < kSamples; ++k)
    for (uint s = 0u; s < kSamples; ++s)
      if ((same[s] & (1u << k)) != 0u) same[s] |= same[k];
  uint mask = same[0];
  for (uint s = 1u; s < kSamples; ++s)
    if (bitCount(same[s]) > bitCount(mask)) mask = same[s];
  // The runner-up: the largest of the other groups (ties: the lowest sample's), if any.
  uint runner = 0u;
  for (uint s = 0u; s < kSamples; ++s)
    if ((mask & (1u << s)) == 0u && bitCount(same[s]) > bitCount(runner)) runner = same[s];
  uint id;
  vec2 mean;
  Pick(mask, ids, id, mean);
  id = ContainingId(p, mask, ids, firsts, id, CoverageMean(PackCoverage(mask, mean)));
  uint winner = id;
  imageStore(u_id, p, uvec4(id));
  imageStore(u_coverage, p, uvec4(PackCoverage(mask, mean)));
  uvec2 record = uvec2(0u);
  if (runner != 0u) {
    Pick(runner, ids, id, mean);
    uint word = PackRunnerUp(runner, mean, kRunnerUpUndecided);
    record = uvec2(ContainingId(p, runner, ids, firsts, id, RunnerUpMean(word)), word);
    // Listed in the blend list, after the edge list (which the uniform pass has finished).
    uint k = atomicAdd(entries[BlendListCounter(edges)].dispatch.w, 1u);
    pixels[BlendListStart(edges) + k] = entry;
  }
  runner_ups[entry] = record;
  return winner;
}

// Where edge list entry `entry`'s runner-up gets its colour: the first neighbour, by angle from
// the direction of its samples' mean (the two either side of it, then the next two out, ...),
// whose shaded id is on its surface, or else its own shading (counted in list.x of the edge
// list's entry, for the frame's statistics).
void DecideRunnerUp(ivec2 p, uint entry, uint edges) {
  uvec2 record = runner_ups[entry];
  if ((record.y & 0xffu) == 0u) return;
  uvec3 tv = SurfaceCorners(record.x);
  vec2 toward = RunnerUpMean(record.y) - vec2(0.5);
  float sector = atan(toward.y, toward.x) / (0.25 * 3.14159265359);
  if (sector < 0.0) sector += 8.0;
  // The two neighbours either side of that direction (counter-clockwise order: the first one
  // first), then the next two out on either side, and so on. Taking the nearer of the two first
  // instead measured worse (tessera-aa-quality edge PSNR: DamagedHelmet 27.02 -> 26.89 dB,
  // Sponza 29.83 -> 29.81, the edge scene unchanged).
  int first = int(floor(sector)) & 7;
  ivec2 size = imageSize(u_id);
  uint source = kRunnerUpShaded;
  for (int k = 0; k < 8 && source == kRunnerUpShaded; ++k) {
    // first, first + 1, first - 1, first + 2, ...
    int n = (first + ((k & 1) == 0 ? -(k / 2) : (k + 1) / 2) + 8) & 7;
    ivec2 q = p + kNeighbours[n];
    if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
    uint other = imageLoad(u_id, q).r;
    if (SameSurface(record.x, other, tv, SurfaceCorners(other))) source = uint(n);
  }
  if (source == kRunnerUpShaded) {
    atomicAdd(entries[edges].list.x, 1u);
    Append(MaterialOf(record.x, edges), kCountPixels);
  }
  runner_ups[entry].y = (record.y & 0x0fffffffu) | (source << 28);
}

void main() {
  const uint mode = kMode;
  uint edges = push.params.y;  // the edge list's entry
  if (mode == kResolveArgs) {  // sizes the dispatch over entry params.x's list
    uint list = push.params.x;
    if (gl_LocalInvocationIndex == 0u)
      entries[list].dispatch.xyz = DispatchFor(entries[list].dispatch.w);
    return;
  }
  uint entry = 0u;
  if (mode == kResolveRunnerUps) {  // one blend list entry each
    if (!BlendListEntry(edges, entry)) return;
    uint packed = pixels[entry];
    DecideRunnerUp(ivec2(packed & 0xffffu, packed >> 16), entry, edges);
    return;
  }
  ivec2 p;
  if (mode == kResolveUniform) {  // an 8x8 tile per workgroup
    uint l = gl_LocalInvocationIndex;
    p = ivec2(gl_WorkGroupID.xy) * 8 + ivec2(l % 8u, l / 8u);
    if (any(greaterThanEqual(p, ivec2(frame.counts.zw)))) return;
  }
  if (mode == kResolveEdges) {  // one edge list entry each
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    entry = group * kShadeGroupSize + gl_LocalInvocationIndex;
    if (entry >= entries[edges].dispatch.w) return;
    uint packed = pixels[entry];
    p = ivec2(packed & 0xffffu, packed >> 16);
  }
  uint ids[kSamples];
  bool uniform_id = true;
#ifdef VIS_RESOLVE_ANALYTIC
  // A pixel is an edge pixel where its 3x3 neighbourhood shows more than one surface.
  if (mode == kResolveEdges) {
    AnalyticSamples(p, ids);
  } else {
    uint own = IdAt(p, ivec2(0));
    for (int k = 0; k < 9; ++k) uniform_id = uniform_id && IdAt(p, ivec2(k % 3 - 1, k / 3 - 1)) == own;
    if (!uniform_id) uniform_id = OneSurfaceAround(p);
    for (uint s = 0u; s < kSamples; ++s) ids[s] = own;
  }
#else
  for (uint s = 0u; s < kSamples; ++s) {
    ids[s] = texelFetch(u_vis, p, int(s)).r;
    uniform_id = uniform_id && ids[s] == ids[0];
  }
#endif
  // The pixels whose surface is the sky are not counted: the classification writes the sky there.
  if (mode == kResolveEdges) {
    uint winner = Group(p, entry, edges, ids);
    if (winner != 0u) Append(MaterialOf(winner, edges), kCountPixels);
  } else if (uniform_id) {  // one triangle (analytic: one surface) or none: at the centre
    imageStore(u_id, p, uvec4(ids[0]));
    imageStore(u_coverage, p, uvec4(PackCoverage((1u << kSamples) - 1u, vec2(0.5))));
    if (ids[0] != 0u) Append(MaterialOf(ids[0], edges), kCountPixels);
  } else {
    pixels[atomicAdd(entries[edges].dispatch.w, 1u)] = uint(p.x) | (uint(p.y) << 16);
  }
}
