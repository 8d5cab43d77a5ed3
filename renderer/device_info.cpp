#include "renderer/device_info.h"

#include <algorithm>
#include <cctype>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace tessera {

namespace {

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return out;
}

int TypeRank(std::string_view type) {
  if (type == "discrete") return 4;
  if (type == "integrated") return 3;
  if (type == "virtual") return 2;
  if (type == "cpu") return 1;
  return 0;
}

}  // namespace

const std::vector<std::string>& DisableableFeatures() {
  static const std::vector<std::string> names = {
      "draw_indirect_count", "multi_draw_indirect", "subgroup_arithmetic", "subgroup_ballot",
      "sampler_minmax",      "visibility_buffer",   "pipeline_statistics", "material_variants",
      "texel_buffers",       "vertex_pulling",      "host_specialization", "sampler_indexing",
      "storage_rg16f"};
  return names;
}

absl::StatusOr<size_t> ChooseDevice(const std::vector<DeviceCandidate>& devices,
                                    std::string_view wanted) {
  const std::string needle = Lower(wanted);
  int best_rank = -1;
  size_t best = 0;
  std::vector<std::string> listed;
  for (size_t i = 0; i < devices.size(); ++i) {
    const DeviceCandidate& d = devices[i];
    listed.push_back(absl::StrCat(d.name, " (", d.type, d.usable ? "" : ", not usable", ")"));
    if (!d.usable) continue;
    if (!needle.empty() && Lower(d.name).find(needle) == std::string::npos) continue;
    if (TypeRank(d.type) > best_rank) {
      best_rank = TypeRank(d.type);
      best = i;
    }
  }
  if (best_rank < 0) {
    return absl::NotFoundError(absl::StrCat(
        wanted.empty()
            ? std::string("no Vulkan 1.3 device with a graphics+compute queue")
            : absl::StrCat("no usable Vulkan device matches '", std::string(wanted), "'"),
        "; devices: [", absl::StrJoin(listed, ", "), "]"));
  }
  return best;
}

}  // namespace tessera
