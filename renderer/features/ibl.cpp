// IBL: ambient light from the procedural sky (renderer/ibl.h), baked into the environment,
// irradiance and prefiltered specular maps (renderer/ibl_maps.h) when the sky changes. It adds
// no pass to the frame: the shading reads the maps through the scene set, and the sky is the
// background.
#include "common/status_macros.h"
#include "renderer/renderer_impl.h"

namespace tessera {

absl::Status Renderer::Impl::PrepareIbl(FrameData& f, Frame& frame) {
  if (!f.s.ibl) return absl::OkStatus();
  // The procedural sky with the first directional light's sun, baked when it changed.
  glm::vec3 sun_dir(0.0f), sun_color(0.0f);
  for (const Light& l : f.global) {
    if (l.type != LightType::kDirectional) continue;
    sun_dir = -l.direction;
    // The glow's scale: the sun's colour at a quarter of its intensity, bounded so a physically
    // scaled sun (lux) does not flood the sky.
    sun_color = l.color * std::clamp(l.intensity * 0.25f, 0.0f, 1.0f);
    break;
  }
  ASSIGN_OR_RETURN(const bool baked, EnsureIbl(DefaultSky(sun_dir, sun_color)));
  frame.stats.ibl_bakes = baked ? 1 : 0;
  return absl::OkStatus();
}

absl::StatusOr<bool> Renderer::Impl::EnsureIbl(const SkyParams& sky) {
  if (!ibl) {
    ASSIGN_OR_RETURN(ibl, IblMaps::Create(*ctx));
  }
  const uint64_t hash = HashBytes(&sky, sizeof(sky));
  if (ibl->baked() && hash == ibl_sky_hash) return false;
  vkDeviceWaitIdle(ctx->device());  // earlier frames may still sample the maps
  executor->BeginOneTime();
  ibl->RecordBake(executor->cmd(), sky);
  if (absl::Status st = executor->SubmitAndWait(/*host_read=*/false); !st.ok()) {
    ibl.reset();  // what it holds is unknown: made and baked afresh next time
    return st;
  }
  ibl_sky_hash = hash;
  return true;
}

}  // namespace tessera
