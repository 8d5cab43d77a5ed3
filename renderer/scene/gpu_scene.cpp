#include "renderer/scene/gpu_scene.h"

#include <stb/stb_image_resize.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <tuple>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/log.h"
#include "renderer/scene/adjacency.h"
#include "renderer/vk/vk_check.h"

namespace tessera {

namespace {

// Nearest power of two in log space, clamped to [4, max_size].
uint32_t RoundPow2(uint32_t v, uint32_t max_size) {
  if (v <= 4) return 4;
  const uint32_t lo = std::bit_floor(v);
  const uint32_t hi = lo << 1;
  const uint32_t r = (static_cast<uint64_t>(v) * v >= static_cast<uint64_t>(lo) * hi) ? hi : lo;
  return std::min(r, std::bit_floor(std::max(max_size, 4u)));
}

uint32_t MipCount(uint32_t w, uint32_t h) {
  return static_cast<uint32_t>(std::bit_width(std::max(w, h)));
}

}  // namespace

DrawPlan PlanDraws(const std::vector<DrawItem>& draws) {
  DrawPlan plan;
  plan.order.resize(draws.size());
  for (uint32_t i = 0; i < draws.size(); ++i) plan.order[i] = i;
  auto key = [&](uint32_t i) {
    const DrawItem& d = draws[i];
    // Blended items keep drawable order; they are sorted per frame.
    const bool blend = d.alpha == AlphaMode::kBlend;
    return std::make_tuple(static_cast<uint32_t>(d.alpha), blend ? 0 : int(d.double_sided),
                           blend ? 0u : d.material, d.drawable);
  };
  std::stable_sort(plan.order.begin(), plan.order.end(),
                   [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
  for (uint32_t i = 0; i < plan.order.size(); ++i) {
    const DrawItem& d = draws[plan.order[i]];
    const bool blend = d.alpha == AlphaMode::kBlend;
    if (blend || plan.segments.empty() || plan.segments.back().group != d.alpha ||
        plan.segments.back().double_sided != d.double_sided ||
        plan.segments.back().material != d.material) {
      plan.segments.push_back({d.alpha, d.double_sided, d.material, i, 0});
    }
    plan.segments.back().item_count++;
    if (d.alpha == AlphaMode::kOpaque) {
      if (plan.batches.empty() || plan.batches.back().double_sided != d.double_sided)
        plan.batches.push_back({d.double_sided, i, 0});
      plan.batches.back().item_count++;
    }
  }
  return plan;
}

namespace {

absl::StatusOr<vk::Buffer> UploadBuffer(vk::Context& ctx, const void* data, size_t size,
                                        VkBufferUsageFlags usage, const std::string& name) {
  absl::StatusOr<vk::Buffer> buffer = vk::Buffer::Create(
      ctx, size, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUsage::kDeviceLocal, name);
  if (!buffer.ok() || size == 0) return buffer;
  ASSIGN_OR_RETURN(vk::Buffer staging,
                   vk::Buffer::Create(ctx, size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                      vk::MemoryUsage::kUpload, name + ".staging"));
  std::memcpy(staging.mapped(), data, size);
  absl::Status st = ctx.SubmitOnce([&](VkCommandBuffer cmd) {
    const VkBufferCopy region{0, 0, size};
    vkCmdCopyBuffer(cmd, staging.handle(), buffer->handle(), 1, &region);
  });
  if (!st.ok()) return st;
  return buffer;
}

}  // namespace

bool MirrorsWinding(const glm::mat4& world) { return glm::determinant(glm::mat3(world)) < 0.0f; }

MirrorPlan PlanMirroredRanges(const CpuScene& scene) {
  MirrorPlan plan;
  plan.first.assign(scene.primitives.size(), kNotMirrored);
  uint64_t next = scene.indices.size();
  for (const Drawable& d : scene.drawables) {
    if (d.primitive >= scene.primitives.size() || !MirrorsWinding(d.world)) continue;
    const Primitive& p = scene.primitives[d.primitive];
    uint32_t& first = plan.first[d.primitive];
    // A skinned mesh's node transform is not its vertices' (glTF ignores it; the joints place
    // them): it keeps its winding. So does a primitive outside the index buffer (a malformed
    // scene) or one whose copy would not fit 32-bit indices.
    if (first != kNotMirrored || p.skinned ||
        uint64_t(p.first_index) + p.index_count > scene.indices.size() ||
        next + p.index_count > uint64_t(UINT32_MAX))
      continue;
    first = uint32_t(next);
    next += p.index_count;
  }
  plan.indices = next - scene.indices.size();
  return plan;
}

void AppendMirroredRanges(const CpuScene& scene, const MirrorPlan& plan,
                          std::vector<uint32_t>& indices, std::vector<uint32_t>& adjacency,
                          std::vector<uint32_t>& surfaces) {
  indices.resize(scene.indices.size() + plan.indices);
  adjacency.resize(indices.size(), kNoNeighbour);
  surfaces.resize(indices.size(), 0);
  for (uint32_t p = 0; p < plan.first.size(); ++p) {
    if (plan.first[p] == kNotMirrored) continue;
    const uint32_t from = scene.primitives[p].first_index, to = plan.first[p];
    for (uint32_t t = 0; t < scene.primitives[p].index_count / 3; ++t) {
      // (a, b, c) -> (a, c, b): its edges a-c, c-b, b-a are the original's third, second and
      // first, so each takes that edge's neighbour (the same triangle numbers).
      const uint32_t i = from + 3 * t, o = to + 3 * t;
      for (std::vector<uint32_t>* corners : {&indices, &surfaces}) {
        std::vector<uint32_t>& c = *corners;
        c[o] = c[i];
        c[o + 1] = c[i + 2];
        c[o + 2] = c[i + 1];
      }
      adjacency[o] = adjacency[i + 2];
      adjacency[o + 1] = adjacency[i + 1];
      adjacency[o + 2] = adjacency[i];
    }
  }
}

namespace {

// A drawable's world matrix and bounds in its record.
void PlaceRecord(const glm::mat4& world, const Aabb& bounds, gpu::GpuDrawable& g) {
  g.world = world;
  // A node scaled to zero (legal glTF, used to hide things) has no inverse: such a drawable
  // covers no pixels, but its matrix must not put NaNs in the buffer.
  const glm::mat3 normal = glm::transpose(glm::inverse(glm::mat3(world)));
  const bool finite = std::isfinite(normal[0][0] + normal[0][1] + normal[0][2] + normal[1][0] +
                                    normal[1][1] + normal[1][2] + normal[2][0] + normal[2][1] +
                                    normal[2][2]);
  g.normal_matrix = glm::mat4(finite ? normal : glm::mat3(1.0f));
  // The bitangent's sign (GpuDrawable::normal_matrix[3][3]): a mirroring transform turns the
  // tangent frame's handedness over, which the shaders' cross(normal, tangent) does not see.
  // (A skinned drawable's posed record has the identity here: its joints are not looked at.)
  g.normal_matrix[3][3] = MirrorsWinding(world) ? -1.0f : 1.0f;
  g.sphere = glm::vec4(bounds.center(), bounds.radius());
  g.aabb_min = glm::vec4(bounds.min, 0.0f);
  g.aabb_max = glm::vec4(bounds.max, 0.0f);
}

gpu::GpuTextureRef MakeTextureRef(const TextureRef& ref, const std::vector<Texture>& textures,
                                  const TextureBucketPlan& plan) {
  gpu::GpuTextureRef out{};
  const glm::mat3 m = ref.uv_transform();
  out.row0 = glm::vec4(m[0][0], m[1][0], m[2][0], 0.0f);
  out.row1 = glm::vec4(m[0][1], m[1][1], m[2][1], 0.0f);
  if (ref.texture < 0 || static_cast<size_t>(ref.texture) >= textures.size()) {
    out.info = glm::ivec4(-1, 0, 0, 0);
    return out;
  }
  const Texture& t = textures[ref.texture];
  const TextureBucketPlan::Slot& slot = plan.slots[ref.texture];
  out.info = glm::ivec4(static_cast<int>(slot.bucket), static_cast<int>(slot.layer),
                        static_cast<int>(std::min(ref.texcoord, 1u)),
                        static_cast<int>(t.wrap_s) | (static_cast<int>(t.wrap_t) << 2));
  return out;
}

float DielectricF0(float ior) {
  const float r = (ior - 1.0f) / (ior + 1.0f);
  return r * r;
}

gpu::GpuMaterial MakeMaterial(const Material& m, const std::vector<Texture>& textures,
                              const TextureBucketPlan& plan) {
  gpu::GpuMaterial g{};
  g.base_color_factor = m.base_color_factor;
  g.emissive = glm::vec4(m.emissive_factor * m.emissive_strength, 0.0f);
  g.params = glm::vec4(m.metallic_factor, m.roughness_factor, m.normal_scale, m.occlusion_strength);
  g.params2 = glm::vec4(m.alpha_cutoff, 0.0f, 0.0f, 0.0f);
  g.flags = glm::uvec4(static_cast<uint32_t>(m.alpha_mode), m.double_sided ? 1u : 0u,
                       m.unlit ? 1u : 0u, 0u);
  g.specular = glm::vec4(DielectricF0(m.ior) * m.specular_color_factor, m.specular_factor);
  g.base_color_tex = MakeTextureRef(m.base_color, textures, plan);
  // An unlit surface reads its base colour only: no other slot is sampled (nor, on devices with
  // a pipeline per set of slots, compiled in).
  const TextureRef none;
  auto lit_only = [&](const TextureRef& ref) {
    return MakeTextureRef(m.unlit ? none : ref, textures, plan);
  };
  g.metallic_roughness_tex = lit_only(m.metallic_roughness);
  g.normal_tex = lit_only(m.normal);
  g.occlusion_tex = lit_only(m.occlusion);
  g.emissive_tex = lit_only(m.emissive);
  g.specular_color_tex = lit_only(m.specular_color);
  g.specular_tex = lit_only(m.specular);
  if (m.unlit) g.emissive = glm::vec4(0.0f);
  return g;
}

// Resamples `img` to w x h RGBA8 (sRGB-correct filtering for colour textures).
std::vector<uint8_t> Resample(const Image& img, uint32_t w, uint32_t h, bool srgb) {
  std::vector<uint8_t> out(static_cast<size_t>(w) * h * 4);
  if (srgb) {
    stbir_resize_uint8_srgb(img.rgba8.data(), img.width, img.height, 0, out.data(), w, h, 0, 4, 3,
                            0);
  } else {
    stbir_resize_uint8(img.rgba8.data(), img.width, img.height, 0, out.data(), w, h, 0, 4);
  }
  return out;
}

// Creates one bucket image, uploads its layers in chunks (bounded staging memory), builds the
// mip chain with blits and leaves it in SHADER_READ_ONLY_OPTIMAL.
absl::StatusOr<vk::Image> UploadBucket(vk::Context& ctx, const TextureBucketPlan::Bucket& b,
                                       const std::vector<const Texture*>& layers,
                                       const std::string& name) {
  vk::ImageDesc desc;
  desc.format = b.srgb ? VK_FORMAT_R8G8B8A8_SRGB : VK_FORMAT_R8G8B8A8_UNORM;
  desc.width = b.width;
  desc.height = b.height;
  desc.mip_levels = MipCount(b.width, b.height);
  desc.array_layers = static_cast<uint32_t>(layers.size());
  desc.usage = VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT |
               VK_IMAGE_USAGE_SAMPLED_BIT;
  desc.view_type = VK_IMAGE_VIEW_TYPE_2D_ARRAY;
  ASSIGN_OR_RETURN(vk::Image image, vk::Image::Create(ctx, desc, name));

  const size_t layer_bytes = static_cast<size_t>(b.width) * b.height * 4;
  const size_t chunk_layers = std::max<size_t>(1, (64u << 20) / layer_bytes);
  for (size_t first = 0; first < layers.size(); first += chunk_layers) {
    const size_t count = std::min(chunk_layers, layers.size() - first);
    absl::StatusOr<vk::Buffer> staging =
        vk::Buffer::Create(ctx, layer_bytes * count, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                           vk::MemoryUsage::kUpload, name + ".staging");
    if (!staging.ok()) return staging.status();
    auto* dst = static_cast<uint8_t*>(staging->mapped());
    for (size_t i = 0; i < count; ++i) {
      const Image& img = *layers[first + i]->image;
      if (img.width == b.width && img.height == b.height) {
        std::memcpy(dst + i * layer_bytes, img.rgba8.data(), layer_bytes);
      } else {
        const std::vector<uint8_t> resized = Resample(img, b.width, b.height, b.srgb);
        std::memcpy(dst + i * layer_bytes, resized.data(), layer_bytes);
      }
    }
    const bool first_chunk = first == 0;
    absl::Status st = ctx.SubmitOnce([&](VkCommandBuffer cmd) {
      vk::ImageTransition t;
      if (first_chunk) {
        t.dst_stage = VK_PIPELINE_STAGE_2_COPY_BIT;
        t.dst_access = VK_ACCESS_2_TRANSFER_WRITE_BIT;
        t.new_layout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
        const VkImageMemoryBarrier2 barrier = vk::MakeImageBarrier(image, t);
        vk::CmdBarrier(cmd, &barrier, 1);
      }
      std::vector<VkBufferImageCopy> regions(count);
      for (size_t i = 0; i < count; ++i) {
        regions[i].bufferOffset = i * layer_bytes;
        regions[i].imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0,
                                       static_cast<uint32_t>(first + i), 1};
        regions[i].imageExtent = {b.width, b.height, 1};
      }
      vkCmdCopyBufferToImage(cmd, staging->handle(), image.handle(),
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                             static_cast<uint32_t>(regions.size()), regions.data());
    });
    if (!st.ok()) return st;
  }

  absl::Status st = ctx.SubmitOnce([&](VkCommandBuffer cmd) {
    const uint32_t levels = desc.mip_levels;
    int32_t w = static_cast<int32_t>(b.width), h = static_cast<int32_t>(b.height);
    for (uint32_t level = 1; level < levels; ++level) {
      // Level-1 becomes a blit source; level is still TRANSFER_DST from the first barrier.
      vk::ImageTransition t{
          VK_PIPELINE_STAGE_2_TRANSFER_BIT,     VK_ACCESS_2_TRANSFER_WRITE_BIT,
          VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_BLIT_BIT,
          VK_ACCESS_2_TRANSFER_READ_BIT,        VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
      const VkImageMemoryBarrier2 barrier = vk::MakeImageBarrier(image, t, level - 1, 1);
      vk::CmdBarrier(cmd, &barrier, 1);
      const int32_t nw = std::max(1, w / 2), nh = std::max(1, h / 2);
      VkImageBlit blit{};
      blit.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, level - 1, 0, desc.array_layers};
      blit.srcOffsets[1] = {w, h, 1};
      blit.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, level, 0, desc.array_layers};
      blit.dstOffsets[1] = {nw, nh, 1};
      vkCmdBlitImage(cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, image.handle(),
                     VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &blit, VK_FILTER_LINEAR);
      w = nw;
      h = nh;
    }
    // All levels but the last are TRANSFER_SRC now; the last is TRANSFER_DST.
    VkImageMemoryBarrier2 barriers[2];
    uint32_t n = 0;
    const vk::ImageTransition to_read_dst{
        VK_PIPELINE_STAGE_2_TRANSFER_BIT,     VK_ACCESS_2_TRANSFER_WRITE_BIT,
        VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT,
        VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    barriers[n++] = vk::MakeImageBarrier(image, to_read_dst, levels - 1, 1);
    if (levels > 1) {
      const vk::ImageTransition to_read_src{
          VK_PIPELINE_STAGE_2_TRANSFER_BIT,     VK_ACCESS_2_TRANSFER_READ_BIT,
          VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT,
          VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
      barriers[n++] = vk::MakeImageBarrier(image, to_read_src, 0, levels - 1);
    }
    vk::CmdBarrier(cmd, barriers, n);
  });
  if (!st.ok()) return st;
  return image;
}

absl::StatusOr<vk::Image> PlaceholderBucket(vk::Context& ctx, uint32_t index) {
  vk::ImageDesc desc;
  desc.format = VK_FORMAT_R8G8B8A8_UNORM;
  desc.usage = VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;
  desc.view_type = VK_IMAGE_VIEW_TYPE_2D_ARRAY;
  ASSIGN_OR_RETURN(
      vk::Image image,
      vk::Image::Create(ctx, desc, absl::StrCat("texture_bucket", index, ".placeholder")));
  absl::Status st = ctx.SubmitOnce([&](VkCommandBuffer cmd) {
    vk::ImageTransition t;
    t.dst_stage = VK_PIPELINE_STAGE_2_CLEAR_BIT;
    t.dst_access = VK_ACCESS_2_TRANSFER_WRITE_BIT;
    t.new_layout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
    VkImageMemoryBarrier2 b = vk::MakeImageBarrier(image, t);
    vk::CmdBarrier(cmd, &b, 1);
    const VkClearColorValue white{{1.0f, 1.0f, 1.0f, 1.0f}};
    const VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdClearColorImage(cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &white, 1,
                         &range);
    const vk::ImageTransition to_read{
        VK_PIPELINE_STAGE_2_CLEAR_BIT,        VK_ACCESS_2_TRANSFER_WRITE_BIT,
        VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT,
        VK_ACCESS_2_SHADER_SAMPLED_READ_BIT,  VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    b = vk::MakeImageBarrier(image, to_read);
    vk::CmdBarrier(cmd, &b, 1);
  });
  if (!st.ok()) return st;
  return image;
}

}  // namespace

TextureBucketPlan PlanTextureBuckets(const std::vector<Texture>& textures, uint32_t max_size) {
  struct Key {
    uint32_t w, h;
    bool srgb;
    auto operator<=>(const Key&) const = default;
  };
  std::map<Key, std::vector<uint32_t>> groups;
  for (uint32_t i = 0; i < textures.size(); ++i) {
    const Texture& t = textures[i];
    const uint32_t w = t.image ? RoundPow2(t.image->width, max_size) : 4;
    const uint32_t h = t.image ? RoundPow2(t.image->height, max_size) : 4;
    groups[{w, h, t.srgb}].push_back(i);
  }
  while (groups.size() > gpu::kMaxTextureBuckets) {
    // Merge the smallest group that has a same-colour-space sibling into the sibling closest
    // in area (its textures get resampled to that size).
    auto victim = groups.end();
    for (auto it = groups.begin(); it != groups.end(); ++it) {
      const bool has_sibling = std::any_of(groups.begin(), groups.end(), [&](const auto& g) {
        return &g != &*it && g.first.srgb == it->first.srgb;
      });
      if (has_sibling && (victim == groups.end() || it->second.size() < victim->second.size()))
        victim = it;
    }
    auto target = groups.end();
    const double area = double(victim->first.w) * victim->first.h;
    for (auto it = groups.begin(); it != groups.end(); ++it) {
      if (it == victim || it->first.srgb != victim->first.srgb) continue;
      const double d = std::abs(std::log2(double(it->first.w) * it->first.h / area));
      if (target == groups.end() ||
          d < std::abs(std::log2(double(target->first.w) * target->first.h / area)))
        target = it;
    }
    target->second.insert(target->second.end(), victim->second.begin(), victim->second.end());
    groups.erase(victim);
  }
  TextureBucketPlan plan;
  plan.slots.resize(textures.size());
  for (auto& [key, members] : groups) {
    std::sort(members.begin(), members.end());
    const uint32_t bucket = static_cast<uint32_t>(plan.buckets.size());
    plan.buckets.push_back({key.w, key.h, key.srgb, static_cast<uint32_t>(members.size())});
    for (uint32_t layer = 0; layer < members.size(); ++layer)
      plan.slots[members[layer]] = {bucket, layer};
  }
  return plan;
}

PoseLayout PlanPoseBuffer(const SceneAnimator& animator) {
  PoseLayout l;
  l.weights_offset = animator.joint_count() * sizeof(glm::mat4);
  l.records_offset = (l.weights_offset + animator.weight_count() * sizeof(float) + 15) / 16 * 16;
  // At least 16 bytes: a scene whose animation moves only cameras and lights has no records.
  l.size = std::max<VkDeviceSize>(16, l.records_offset + animator.drawables().size() *
                                                             sizeof(gpu::GpuDrawable));
  return l;
}

namespace {

// What UploadAnimation allocates besides the copies: the joints and weights of every vertex (a
// 16-byte stand-in without skins), the morph deltas (likewise) and the pose buffer.
uint64_t AnimationBytes(const CpuScene& scene, const SceneAnimator& animator) {
  return (animator.skinned() ? scene.vertices.size() * 2 * sizeof(glm::uvec4) : 16) +
         std::max<size_t>(1, animator.skin_jobs()) * sizeof(gpu::GpuSkinJob) +
         std::max<uint64_t>(16, scene.morph_deltas.size() * gpu::kMorphDeltaFloats * 4) +
         PlanPoseBuffer(animator).size + animator.copy_vertices() * sizeof(Vertex);
}

}  // namespace

absl::Status GpuScene::Keep(vk::Buffer& dst, absl::StatusOr<vk::Buffer> src) {
  if (!src.ok()) return src.status();
  device_bytes_ += src->size();
  dst = std::move(*src);
  return absl::OkStatus();
}

absl::Status GpuScene::MakeTexelViews(vk::Context& ctx, const std::string& name) {
  bool indices = false, vertices = false, drawables = false, surfaces = false;
  ASSIGN_OR_RETURN(index_texels_, vk::CreateTexelView(ctx, indices_, VK_FORMAT_R32_UINT, 4,
                                                      name + ".index_texels", &indices));
  ASSIGN_OR_RETURN(surface_texels_, vk::CreateTexelView(ctx, surfaces_, VK_FORMAT_R32_UINT, 4,
                                                        name + ".surface_texels", &surfaces));
  ASSIGN_OR_RETURN(vertex_texels_, vk::CreateTexelView(ctx, vertices_, VK_FORMAT_R32G32_UINT, 8,
                                                       name + ".vertex_texels", &vertices));
  ASSIGN_OR_RETURN(drawable_texels_,
                   vk::CreateTexelView(ctx, drawables_, VK_FORMAT_R32G32B32A32_UINT, 16,
                                       name + ".drawable_texels", &drawables));
  const bool whole = indices && vertices && drawables && surfaces;
  vis_texels_ = whole && ctx.info().texel_buffers;
  if (!whole)
    Log().info("{}: the visibility passes read its geometry from storage buffers (more texels "
               "than maxTexelBufferElements, {})",
               name, ctx.limits().maxTexelBufferElements);
  return absl::OkStatus();
}

absl::Status GpuScene::UploadAnimation(vk::Context& ctx, const CpuScene& scene) {
  const std::string& n = scene.name;
  const SceneAnimator& a = *animator_;
  const bool skins = a.skinned();
  std::vector<glm::uvec4> attributes(skins ? scene.vertices.size() * 2 : 1, glm::uvec4(0));
  if (skins) {
    for (size_t v = 0; v < scene.vertices.size(); ++v) {
      attributes[2 * v] = scene.skin_joints[v];
      std::memcpy(&attributes[2 * v + 1], &scene.skin_weights[v], sizeof(glm::vec4));
    }
  }
  RETURN_IF_ERROR(Keep(skin_attributes_,
                         UploadBuffer(ctx, attributes.data(), attributes.size() * sizeof(glm::uvec4),
                                      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, n + ".skin_attributes")));
  std::vector<float> deltas(std::max<size_t>(4, scene.morph_deltas.size() * gpu::kMorphDeltaFloats),
                            0.0f);
  for (size_t i = 0; i < scene.morph_deltas.size(); ++i) {
    const MorphDelta& d = scene.morph_deltas[i];
    float* o = &deltas[i * gpu::kMorphDeltaFloats];
    for (int k = 0; k < 3; ++k) {
      o[k] = d.position[k];
      o[3 + k] = d.normal[k];
      o[6 + k] = d.tangent[k];
    }
  }
  RETURN_IF_ERROR(Keep(morph_deltas_,
                         UploadBuffer(ctx, deltas.data(), deltas.size() * sizeof(float),
                                      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, n + ".morph_deltas")));
  const PoseLayout layout = PlanPoseBuffer(a);
  RETURN_IF_ERROR(Keep(pose_, vk::Buffer::Create(
                                    ctx, layout.size,
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                        VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                    vk::MemoryUsage::kDynamic, n + ".pose")));
  pose_weights_offset_ = layout.weights_offset;
  pose_records_offset_ = layout.records_offset;
  pose_copies_.clear();
  for (size_t i = 0; i < a.drawables().size(); ++i) {
    pose_copies_.push_back({pose_records_offset_ + i * sizeof(gpu::GpuDrawable),
                            a.drawables()[i].drawable * sizeof(gpu::GpuDrawable),
                            sizeof(gpu::GpuDrawable)});
  }
  // One job per deformed drawable: its primitive's rest vertices into its copy.
  std::vector<gpu::GpuSkinJob> jobs;
  skin_groups_ = 0;
  for (const AnimatedDrawable& ad : a.drawables()) {
    if (!ad.deformed || scene.primitives[ad.primitive].vertex_count == 0) continue;
    const Primitive& p = scene.primitives[ad.primitive];
    gpu::GpuSkinJob job{};
    job.range = glm::uvec4(p.first_vertex, ad.first_vertex, p.vertex_count,
                           (ad.skin >= 0 ? gpu::kSkinJobSkinned : 0u) |
                               (p.flat_normals ? gpu::kSkinJobFlat : 0u));
    job.pose = glm::uvec4(ad.joint_base, uint32_t(pose_weights_offset_ / 4) + ad.weight_base,
                          p.morph_targets, uint32_t(p.first_morph_delta));
    job.groups = glm::uvec4(skin_groups_, 0, 0, 0);
    skin_groups_ += (p.vertex_count + gpu::kSkinGroupSize - 1) / gpu::kSkinGroupSize;
    jobs.push_back(job);
  }
  if (jobs.empty()) jobs.push_back(gpu::GpuSkinJob{});  // keep the binding valid
  RETURN_IF_ERROR(Keep(skin_jobs_, UploadBuffer(ctx, jobs.data(),
                                                  jobs.size() * sizeof(gpu::GpuSkinJob),
                                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                                  n + ".skin_jobs")));
  // The copies hold the rest vertices until the first pose (nothing to do for a scene whose
  // animation moves only cameras and lights).
  pose_pending_ = !a.drawables().empty();
  return absl::OkStatus();
}

bool GpuScene::Pose(int animation, double scene_time, bool loop) {
  if (!animator_ || !animator_->Pose(animation, scene_time, loop)) return false;
  const SceneAnimator& a = *animator_;
  auto* base = static_cast<uint8_t*>(pose_.mapped());
  if (a.joint_count() > 0)
    std::memcpy(base, a.joints().data(), a.joint_count() * sizeof(glm::mat4));
  if (a.weight_count() > 0)
    std::memcpy(base + pose_weights_offset_, a.weights().data(), a.weight_count() * sizeof(float));
  auto* records = reinterpret_cast<gpu::GpuDrawable*>(base + pose_records_offset_);
  if (a.moves_lights()) a.PlaceLights(&lights_);
  bounds_ = static_bounds_;
  for (size_t i = 0; i < a.drawables().size(); ++i) {
    const uint32_t d = a.drawables()[i].drawable;
    gpu::GpuDrawable& g = records_[i];
    PlaceRecord(a.world()[i], a.bounds()[i], g);
    records[i] = g;
    draws_[item_of_drawable_[d]].world_bounds = a.bounds()[i];
    bounds_.extend(a.bounds()[i]);
  }
  pose_pending_ = !a.drawables().empty();
  ++pose_serial_;
  return true;
}

uint64_t EstimateDeviceBytes(const CpuScene& scene, uint32_t max_texture_size,
                             uint64_t uniform_align) {
  // The same sizes Upload passes to UploadBuffer and counts for its texture buckets.
  const uint64_t materials = std::max<size_t>(1, scene.materials.size());
  const uint64_t drawables = std::max<size_t>(1, scene.drawables.size());
  const uint64_t align = std::max<uint64_t>(16, uniform_align);
  const uint64_t stride = (sizeof(gpu::GpuMaterial) + align - 1) / align * align;
  // The indices, their adjacency and their surface indices (one word each, at least one).
  // With the mirrored drawables' copies (PlanMirroredRanges).
  const uint64_t indices = scene.indices.size() + PlanMirroredRanges(scene).indices;
  uint64_t bytes = scene.vertices.size() * sizeof(Vertex) + indices * sizeof(uint32_t) +
                   2 * std::max<uint64_t>(1, indices) * sizeof(uint32_t) +
                   materials * (sizeof(gpu::GpuMaterial) + stride) +
                   drawables * (sizeof(gpu::GpuDrawable) + sizeof(gpu::GpuCullItem));
  for (const TextureBucketPlan::Bucket& b : PlanTextureBuckets(scene.textures, max_texture_size).buckets)
    bytes += uint64_t(b.width) * b.height * 4 * b.layers * 4 / 3;
  const std::unique_ptr<SceneAnimator> a = SceneAnimator::Create(scene);
  if (a) bytes += AnimationBytes(scene, *a);
  // A scene without vertices uploads one, for its texel view (UploadBuffers).
  if (scene.vertices.empty() && (!a || a->copy_vertices() == 0)) bytes += sizeof(Vertex);
  return bytes;
}

GpuScene::~GpuScene() = default;

absl::StatusOr<std::unique_ptr<GpuScene>> GpuScene::Upload(vk::Context& ctx, const CpuScene& scene,
                                                           VkDescriptorSetLayout material_layout,
                                                           VkDescriptorSetLayout bucket_layout) {
  auto gs = std::make_unique<GpuScene>();
  gs->device_ = ctx.device();
  static std::atomic<uint64_t> next_serial{1};
  gs->serial_ = next_serial++;
  const std::string& n = scene.name;
  const uint32_t max_size = std::min<uint32_t>(kMaxTextureSide, ctx.info().max_image_dimension);
  const TextureBucketPlan plan = PlanTextureBuckets(scene.textures, max_size);
  for (const auto& b : plan.buckets) {
    if (b.layers > ctx.info().max_array_layers) {
      return absl::InvalidArgumentError(absl::StrCat(n, ": ", b.layers, " textures of ", b.width,
                                                     "x", b.height, " exceed the device's ",
                                                     ctx.info().max_array_layers, " array layers"));
    }
  }

  std::vector<gpu::GpuMaterial> materials;
  materials.reserve(scene.materials.size());
  for (const Material& m : scene.materials)
    materials.push_back(MakeMaterial(m, scene.textures, plan));
  if (materials.empty()) materials.push_back(MakeMaterial(Material{}, scene.textures, plan));
  // Where a primitive has COLOR_0, its material's shading reads the vertices' colours (the
  // visibility shading fetches them only then; every other vertex is white).
  for (const Primitive& p : scene.primitives)
    if (p.vertex_colors && p.material < materials.size()) materials[p.material].flags.w = 1u;

  std::vector<gpu::GpuDrawable> drawables;
  std::vector<gpu::GpuCullItem> items;
  gs->animator_ = SceneAnimator::Create(scene);
  gs->PlanScene(scene, &drawables, &items);
  RETURN_IF_ERROR(gs->UploadBuffers(ctx, scene, materials, drawables, items));
  RETURN_IF_ERROR(gs->UploadTextures(ctx, scene, plan));
  RETURN_IF_ERROR(gs->WriteMaterialSets(ctx, materials, material_layout, bucket_layout));
  gs->lights_ = scene.lights;
  gs->bounds_ = scene.bounds;
  return gs;
}

void GpuScene::PlanScene(const CpuScene& scene, std::vector<gpu::GpuDrawable>* drawables_out,
                         std::vector<gpu::GpuCullItem>* items_out) {
  std::vector<gpu::GpuDrawable>& drawables = *drawables_out;
  drawables.reserve(scene.drawables.size());
  // Where each drawable's vertices are: a deformed drawable draws its own copy.
  std::vector<uint32_t> first_vertex(scene.drawables.size());
  std::vector<uint8_t> moves(scene.drawables.size(), 0);
  for (uint32_t i = 0; i < scene.drawables.size(); ++i)
    first_vertex[i] = scene.primitives[scene.drawables[i].primitive].first_vertex;
  if (animator_) {
    for (const AnimatedDrawable& ad : animator_->drawables()) {
      first_vertex[ad.drawable] = ad.first_vertex;
      moves[ad.drawable] = 1;
    }
  }
  // A mirrored drawable draws its primitive's copy wound the other way (PlanMirroredRanges).
  mirrors_ = PlanMirroredRanges(scene);
  for (uint32_t i = 0; i < scene.drawables.size(); ++i) {
    const Drawable& d = scene.drawables[i];
    const Primitive& p = scene.primitives[d.primitive];
    const Material& m = scene.materials.empty() ? Material{} : scene.materials[p.material];
    gpu::GpuDrawable g{};
    PlaceRecord(d.world, d.world_bounds, g);
    const uint32_t material = scene.materials.empty() ? 0u : p.material;
    const uint32_t first_index = mirrors_.FirstIndex(scene, d);
    g.ids = glm::uvec4(d.primitive, material, first_index, first_vertex[i]);
    drawables.push_back(g);
    max_draw_triangles_ = std::max(max_draw_triangles_, p.index_count / 3);
    draws_.push_back({i, material, first_index, p.index_count,
                      static_cast<int32_t>(first_vertex[i]), m.alpha_mode, m.double_sided,
                      d.world_bounds});
    if (!moves[i]) static_bounds_.extend(d.world_bounds);
  }
  if (animator_) {  // the moving drawables' records, which Pose rewrites
    for (const AnimatedDrawable& ad : animator_->drawables())
      records_.push_back(drawables[ad.drawable]);
  }
  if (drawables.empty()) drawables.push_back(gpu::GpuDrawable{});  // keep the binding valid
  plan_ = PlanDraws(draws_);
  {
    std::vector<DrawItem> ordered;
    ordered.reserve(draws_.size());
    for (uint32_t i : plan_.order) ordered.push_back(draws_[i]);
    draws_ = std::move(ordered);
  }
  if (animator_) {
    item_of_drawable_.assign(scene.drawables.size(), 0);
    for (uint32_t i = 0; i < draws_.size(); ++i) item_of_drawable_[draws_[i].drawable] = i;
  }
  std::vector<gpu::GpuCullItem>& items = *items_out;
  items.resize(std::max<size_t>(1, draws_.size()));
  for (const DrawSegment& seg : plan_.segments) {
    for (uint32_t i = seg.first_item; i < seg.first_item + seg.item_count; ++i) {
      const DrawItem& d = draws_[i];
      gpu::GpuCullItem& c = items[i];
      c.draw = glm::uvec4(d.first_index, d.index_count, static_cast<uint32_t>(d.vertex_offset),
                          d.drawable);
      c.slot = glm::uvec4(uint32_t(&seg - plan_.segments.data()), seg.first_item, ~0u, 0u);
      c.flags.x = i + 1 == seg.first_item + seg.item_count ? 1u : 0u;
    }
  }
  for (uint32_t b = 0; b < plan_.batches.size(); ++b) {
    const DrawBatch& batch = plan_.batches[b];
    for (uint32_t i = batch.first_item; i < batch.first_item + batch.item_count; ++i) {
      items[i].slot.z = b;
      items[i].slot.w = batch.first_item;
      if (i + 1 == batch.first_item + batch.item_count) items[i].flags.x |= 2u;
    }
  }
}

absl::Status GpuScene::UploadBuffers(vk::Context& ctx, const CpuScene& scene,
                                     const std::vector<gpu::GpuMaterial>& materials,
                                     const std::vector<gpu::GpuDrawable>& drawables,
                                     const std::vector<gpu::GpuCullItem>& items) {
  const std::string& n = scene.name;
  // The visibility passes read triangles from both buffers, and the drawables' records: as
  // texel buffers where the device has them (MakeTexelViews).
  constexpr VkBufferUsageFlags texel = VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT;
  constexpr VkBufferUsageFlags kVertexUsage =
      VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
      VK_BUFFER_USAGE_TRANSFER_SRC_BIT | texel;  // and read back by tests (ReadVerticesForTesting)
  // An animated scene's deformed drawables have their copies after the scene's vertices. skin.comp
  // indexes every buffer it reads by 32-bit float offsets: checked before anything is made.
  if (animator_) {
    const SceneAnimator& a = *animator_;
    constexpr uint64_t k32 = uint64_t(1) << 32;
    if (scene.morph_deltas.size() * gpu::kMorphDeltaFloats >= k32 ||
        (scene.vertices.size() + a.copy_vertices()) * gpu::kVertexFloats >= k32 ||
        PlanPoseBuffer(a).size / sizeof(float) >= k32)
      return absl::InvalidArgumentError(absl::StrCat(
          n, ": too many animated vertices, joints or morph deltas for 32-bit indices"));
  }
  // What every frame binds whole as one storage buffer must fit the device's range (lavapipe:
  // 128 MiB). The index and vertex buffers of a still scene need not: the draws read them as
  // vertex input, the visibility passes through texel views or, where those do not cover them,
  // not at all (Renderer::Impl::CheckVisibilityIds). Nor need a scene's whose animation only
  // moves nodes: only skinning and morph targets (skin.comp) bind the vertices, the deltas, the
  // joints and the pose, and TAA's motion pass a copy of the posed vertices.
  {
    const uint64_t range = ctx.limits().maxStorageBufferRange;
    using Need = std::pair<std::string, uint64_t>;
    std::vector<Need> whole = {
        {absl::StrCat(materials.size(), " materials"), materials.size() * sizeof(gpu::GpuMaterial)},
        {absl::StrCat(drawables.size(), " drawables"), drawables.size() * sizeof(gpu::GpuDrawable)},
        {absl::StrCat(items.size(), " culling records"), items.size() * sizeof(gpu::GpuCullItem)}};
    if (animator_ && animator_->copy_vertices() > 0) {
      const SceneAnimator& a = *animator_;
      const uint64_t posed = scene.vertices.size() + a.copy_vertices();
      whole.push_back({absl::StrCat(posed, " vertices (deformed: skinned or morphed)"),
                       posed * sizeof(Vertex)});
      whole.push_back({absl::StrCat(scene.morph_deltas.size(), " morph target deltas"),
                       scene.morph_deltas.size() * gpu::kMorphDeltaFloats * sizeof(float)});
      if (a.skinned())
        whole.push_back({absl::StrCat(scene.vertices.size(), " vertices' joints and weights"),
                         scene.vertices.size() * 2 * sizeof(glm::uvec4)});
      whole.push_back({"pose (joint matrices, weights, records)", PlanPoseBuffer(a).size});
    }
    for (const auto& [what, bytes] : whole) {
      if (bytes > range)
        return absl::InvalidArgumentError(absl::StrCat(
            n, ": its ", what, ": ", bytes, " bytes in one storage buffer, more than the "
            "device's maxStorageBufferRange (", range, " bytes)"));
    }
  }
  std::vector<Vertex> with_copies;
  if (animator_) with_copies = animator_->VertexData(scene);
  const bool own = animator_ || scene.vertices.empty();
  // A buffer holds at least one texel for its view (a scene may have no geometry).
  if (own && with_copies.empty()) with_copies.resize(1);
  const std::vector<Vertex>& vertices = own ? with_copies : scene.vertices;
  absl::Status st = Keep(
      vertices_, UploadBuffer(ctx, vertices.data(), vertices.size() * sizeof(Vertex),
                              kVertexUsage, n + ".vertices"));
  if (st.ok() && animator_) st = UploadAnimation(ctx, scene);
  if (!st.ok()) return st;
  // Each index's neighbour and the vertex standing for it in vis_mlaa's surface test, and the
  // mirrored drawables' copies after the scene's indices.
  std::vector<uint32_t> adjacency = TriangleAdjacency(scene);
  std::vector<uint32_t> surfaces = SurfaceIndices(scene);
  std::vector<uint32_t> mirrored;
  if (mirrors_.indices > 0) {
    mirrored = scene.indices;
    AppendMirroredRanges(scene, mirrors_, mirrored, adjacency, surfaces);
  }
  const std::vector<uint32_t>& indices = mirrors_.indices > 0 ? mirrored : scene.indices;
  st = Keep(indices_,
                UploadBuffer(ctx, indices.data(), indices.size() * sizeof(uint32_t),
                             VK_BUFFER_USAGE_INDEX_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                 texel,
                             n + ".indices"));
  if (st.ok()) {
    if (adjacency.empty()) adjacency.push_back(kNoNeighbour);  // keep the binding valid
    st = Keep(adjacency_, UploadBuffer(ctx, adjacency.data(), adjacency.size() * sizeof(uint32_t),
                                       VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, n + ".adjacency"));
  }
  if (st.ok()) {
    if (surfaces.empty()) surfaces.push_back(0);  // keep the binding valid
    st = Keep(surfaces_, UploadBuffer(ctx, surfaces.data(), surfaces.size() * sizeof(uint32_t),
                                      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | texel,
                                      n + ".surfaces"));
  }
  if (!st.ok()) return st;

  st = Keep(materials_,
              UploadBuffer(ctx, materials.data(), materials.size() * sizeof(gpu::GpuMaterial),
                           VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, n + ".materials"));
  if (st.ok())  // PlanScene keeps one record at least
    st = Keep(drawables_,
                UploadBuffer(ctx, drawables.data(), drawables.size() * sizeof(gpu::GpuDrawable),
                             // a vertex buffer for pulled vertices (common/vis_pull.glsl)
                             VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_VERTEX_BUFFER_BIT |
                                 texel,
                             n + ".drawables"));
  if (st.ok())
    st =
        Keep(cull_items_, UploadBuffer(ctx, items.data(), items.size() * sizeof(gpu::GpuCullItem),
                                         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, n + ".cull_items"));
  if (!st.ok()) return st;

  RETURN_IF_ERROR(MakeTexelViews(ctx, n));

  // The same materials for uniform reads, one aligned range per material (set 1, binding 0).
  const VkDeviceSize align =
      std::max<VkDeviceSize>(16, ctx.limits().minUniformBufferOffsetAlignment);
  const VkDeviceSize stride = (sizeof(gpu::GpuMaterial) + align - 1) / align * align;
  material_stride_ = stride;
  std::vector<uint8_t> padded(stride * materials.size(), 0);
  for (size_t i = 0; i < materials.size(); ++i)
    std::memcpy(padded.data() + i * stride, &materials[i], sizeof(gpu::GpuMaterial));
  st = Keep(material_uniforms_,
              UploadBuffer(ctx, padded.data(), padded.size(), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
                           n + ".material_uniforms"));
  if (!st.ok()) return st;

  return absl::OkStatus();
}

absl::Status GpuScene::UploadTextures(vk::Context& ctx, const CpuScene& scene,
                                      const TextureBucketPlan& plan) {
  const std::string& n = scene.name;
  const uint32_t bucket_count = std::max<uint32_t>(1, uint32_t(plan.buckets.size()));
  for (uint32_t b = 0; b < bucket_count; ++b) {
    absl::StatusOr<vk::Image> image;
    if (b < plan.buckets.size()) {
      std::vector<const Texture*> layers(plan.buckets[b].layers);
      for (uint32_t t = 0; t < scene.textures.size(); ++t)
        if (plan.slots[t].bucket == b) layers[plan.slots[t].layer] = &scene.textures[t];
      for (const Texture* t : layers)
        if (!t || !t->image || t->image->rgba8.empty())
          return absl::InvalidArgumentError(absl::StrCat(n, ": a texture has no decoded image"));
      image = UploadBucket(ctx, plan.buckets[b], layers, absl::StrCat(n, ".texture_bucket", b));
      if (image.ok()) {
        const auto& d = image->desc();
        device_bytes_ += uint64_t(d.width) * d.height * 4 * d.array_layers * 4 / 3;
      }
    } else {
      image = PlaceholderBucket(ctx, b);
    }
    if (!image.ok()) return image.status();
    buckets_.push_back(std::move(*image));
  }

  VkSamplerCreateInfo si{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  si.magFilter = VK_FILTER_LINEAR;
  si.minFilter = VK_FILTER_LINEAR;
  si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_LINEAR;
  // Repeat in hardware; clamp and mirror are applied to the uv in the shader per texture.
  si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_REPEAT;
  si.anisotropyEnable = ctx.info().max_anisotropy > 1.0f;
  si.maxAnisotropy = ctx.info().max_anisotropy;
  si.maxLod = VK_LOD_CLAMP_NONE;
  ASSIGN_OR_RETURN(sampler_, vk::Sampler::Create(ctx, si, n + ".sampler"));

  return absl::OkStatus();
}

absl::Status GpuScene::WriteMaterialSets(vk::Context& ctx,
                                         const std::vector<gpu::GpuMaterial>& materials,
                                         VkDescriptorSetLayout material_layout,
                                         VkDescriptorSetLayout bucket_layout) {
  // One texture set per material; slots without a texture point at bucket 0 (never sampled).
  // And the bucket set, where asked for.
  const uint32_t material_count = uint32_t(materials.size());
  const uint32_t bucket_sets = bucket_layout ? 1u : 0u;
  const VkDescriptorPoolSize pool_sizes[] = {
      {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
       material_count * gpu::kMaterialTextureSlots + bucket_sets * gpu::kMaxTextureBuckets},
      {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, material_count}};
  VkDescriptorPoolCreateInfo dpi{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpi.maxSets = material_count + bucket_sets;
  dpi.poolSizeCount = 2;
  dpi.pPoolSizes = pool_sizes;
  VK_RETURN_IF_ERROR(
      vkCreateDescriptorPool(ctx.device(), &dpi, nullptr, material_pool_.Replace(ctx.device())),
      "material descriptor pool");
  std::vector<VkDescriptorSetLayout> layouts(material_count, material_layout);
  material_sets_.resize(material_count);
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = material_pool_.get();
  ai.descriptorSetCount = material_count;
  ai.pSetLayouts = layouts.data();
  VK_RETURN_IF_ERROR(vkAllocateDescriptorSets(ctx.device(), &ai, material_sets_.data()),
                     "material descriptor sets");
  std::vector<VkDescriptorImageInfo> infos(size_t(material_count) * gpu::kMaterialTextureSlots);
  std::vector<VkDescriptorBufferInfo> buffer_infos(material_count);
  std::vector<VkWriteDescriptorSet> writes;
  material_textures_.assign(material_count, 0);
  for (uint32_t m = 0; m < material_count; ++m) {
    const gpu::GpuMaterial& g = materials[m];
    const gpu::GpuTextureRef* slots[gpu::kMaterialTextureSlots] = {
        &g.base_color_tex, &g.metallic_roughness_tex, &g.normal_tex,  &g.occlusion_tex,
        &g.emissive_tex,   &g.specular_color_tex,     &g.specular_tex};
    VkDescriptorImageInfo* info = &infos[size_t(m) * gpu::kMaterialTextureSlots];
    if (g.flags.w != 0u || !ctx.info().material_variants)
      material_textures_[m] |= gpu::kMaterialVertexColors;
    const bool tinted = g.specular_color_tex.info.x >= 0 || g.specular.r != g.specular.g ||
                        g.specular.g != g.specular.b;
    if (tinted || !ctx.info().material_variants)
      material_textures_[m] |= gpu::kMaterialTintedSpecular;
    for (uint32_t k = 0; k < gpu::kMaterialTextureSlots; ++k) {
      if (slots[k]->info.x >= 0 || !ctx.info().material_variants)
        material_textures_[m] |= 1u << k;
      const int bucket = std::max(0, slots[k]->info.x);
      info[k] = {sampler_.handle(), buckets_[bucket].view(),
                 VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    }
    buffer_infos[m] = {material_uniforms_.handle(), m * material_stride_, sizeof(gpu::GpuMaterial)};
    VkWriteDescriptorSet u{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    u.dstSet = material_sets_[m];
    u.dstBinding = gpu::kBindingMaterialUniform;
    u.descriptorCount = 1;
    u.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    u.pBufferInfo = &buffer_infos[m];
    writes.push_back(u);
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = material_sets_[m];
    w.dstBinding = gpu::kBindingBaseColorTex;
    w.descriptorCount = gpu::kMaterialTextureSlots;  // consecutive bindings
    w.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w.pImageInfo = info;
    writes.push_back(w);
  }
  std::array<VkDescriptorImageInfo, gpu::kMaxTextureBuckets> bucket_infos;
  if (bucket_layout) {
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &bucket_layout;
    VK_RETURN_IF_ERROR(vkAllocateDescriptorSets(ctx.device(), &ai, &bucket_set_),
                       "bucket descriptor set");
    for (uint32_t b = 0; b < gpu::kMaxTextureBuckets; ++b) {
      bucket_infos[b] = {sampler_.handle(), buckets_[b < buckets_.size() ? b : 0].view(),
                         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    }
    VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstSet = bucket_set_;
    w.dstBinding = gpu::kBindingBuckets;
    w.descriptorCount = gpu::kMaxTextureBuckets;
    w.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    w.pImageInfo = bucket_infos.data();
    writes.push_back(w);
  }
  vkUpdateDescriptorSets(ctx.device(), uint32_t(writes.size()), writes.data(), 0, nullptr);
  texture_sets_ = material_textures_;
  std::sort(texture_sets_.begin(), texture_sets_.end());
  texture_sets_.erase(std::unique(texture_sets_.begin(), texture_sets_.end()), texture_sets_.end());

  return absl::OkStatus();
}

}  // namespace tessera
