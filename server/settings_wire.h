#pragma once
// Render settings on the wire: v1::RenderSettings <-> Settings, row by row of the settings table
// (renderer/settings_table.h) through protobuf reflection, so a setting is converted by its name
// and no field list is written here. Proto enums put UNSPECIFIED at 0: wire value = renderer
// value + 1. Linked by the server (tessera_wire) and the `tessera` CLI; no gRPC, no Vulkan.
#include <cstdint>

#include "absl/status/statusor.h"
#include "renderer/settings.h"
#include "renderer/settings_table.h"
#include "tessera/v1/render_service.pb.h"
#include "tessera/v1/settings.pb.h"

namespace tessera::server {

// `base` with every field set in `update` replaced. INVALID_ARGUMENT naming the field for an
// unknown enum value or an out-of-range result (ValidateSettings).
absl::StatusOr<Settings> MergeSettings(const Settings& base, const v1::RenderSettings& update);

// Every field of `s` into `out`.
void ToProto(const Settings& s, v1::RenderSettings* out);
// Only the rows marked in `fields` (e.g. the ones a command line named); the rest left as they are.
void ToProto(const Settings& s, const SettingMask& fields, v1::RenderSettings* out);

// The names each enum setting accepts, the sample counts (of `sample_counts`, bit n = 2^n) and
// tile sizes on offer, and one SettingSpec per row of the table.
void FillChoices(uint32_t sample_counts, v1::SettingChoices* out);

}  // namespace tessera::server
