#pragma once
// The limits the glTF importer enforces on an untrusted asset. Each is checked before the
// memory it bounds is allocated: sizes and counts come from the JSON (pre-scan) or the image
// headers, never from what a parser built. Exceeding one is RESOURCE_EXHAUSTED with a message
// that names the limit, e.g. "Box.gltf: nodes: 70000 nodes exceed the max_nodes limit (65536)".
//
// Free of other headers so the server options, flag parsing and GetServerInfo can use it.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

struct ImportLimits {
  uint64_t max_json_bytes = 64ull << 20;  // the JSON text (.gltf, or a .glb's JSON chunk)
  uint32_t max_json_depth = 64;           // nesting of arrays/objects (tinygltf recurses)
  uint64_t max_json_values = 1ull << 20;  // values in the JSON (what tinygltf builds grows with it)
  uint32_t max_nodes = 1u << 18;
  uint32_t max_node_depth = 256;  // root = depth 1
  uint32_t max_meshes = 1u << 16;
  uint32_t max_primitives = 1u << 18;              // over all meshes
  uint64_t max_accessor_elements = 1ull << 26;     // count of one accessor
  uint64_t max_accessor_bytes = 1ull << 30;        // count x element size of one accessor
  uint64_t max_vertices = 1ull << 26;              // the scene vertex buffer, after expansion
  uint64_t max_indices = 1ull << 28;               // the scene index buffer (triangle lists)
  uint32_t max_image_dimension = 16384;            // per side
  uint64_t max_image_bytes = 256ull << 20;         // one decoded image (RGBA8)
  uint64_t max_total_image_bytes = 1ull << 30;     // all decoded images together
  uint32_t max_textures = 4096;
  uint32_t max_materials = 16384;
  uint32_t max_lights = 4096;                      // KHR_lights_punctual lights
  uint32_t max_drawables = 1u << 20;  // mesh primitives placed by nodes (x their instances)
  uint64_t max_decoded_bytes = 1ull << 30;         // what Draco and meshopt data decode to,
                                                   // all together (compressed meshes)
  uint64_t max_animation_keys = 1ull << 24;        // key times over all animation samplers
  uint32_t max_skin_joints = 1024;                 // joints of one skin
  uint32_t max_morph_targets = 256;                // morph targets of one mesh
};

// The name (as in flags and messages) and address of every limit, in declaration order.
struct ImportLimitField {
  const char* name;
  bool is_64bit;
  uint32_t ImportLimits::*u32;
  uint64_t ImportLimits::*u64;
  uint64_t Get(const ImportLimits& l) const { return is_64bit ? l.*u64 : l.*u32; }
};
const std::vector<ImportLimitField>& ImportLimitFields();

// Applies "name=value,name=value" (names as in ImportLimitFields) to `limits`. Returns an
// empty string, or what is wrong ("unknown limit 'x'", "max_nodes: '-1' is not a number").
std::string ParseImportLimits(std::string_view spec, ImportLimits* limits);

}  // namespace tessera
