// The frame, as one list of features in the order they run. Each feature's Setup adds its
// passes only when the settings and the scene call for them.
#include "renderer/features/features.h"

namespace tessera {

FramePlan PlanFrame(const Settings& settings, const FrameFeatures& features) {
  GraphBuilder b(settings, features);
  SetupSkinning(b);      // an animated scene's pose, before anything reads the geometry
  SetupCulling(b);       // gpu culling: indirect draw lists from the drawables
  SetupDepth(b);         // depth (or visibility) first, so shading runs once per pixel
  SetupOcclusion(b);     // gpu_occlusion: what became visible against the first phase's depth
  SetupLightCulling(b);  // forward+: per-tile light lists
  SetupShadows(b);       // shadow maps and ambient obscurance, before the shading reads them
  SetupSsao(b);
  SetupVisMlaa(b);            // vis_mlaa resolves its samples to one surface per pixel ...
  SetupVisibilityShading(b);  // ... it and the visibility pipeline shade each pixel once ...
  SetupGeometricAa(b);        // ... (vis_mlaa then blends its partly covered pixels) ...
  SetupForward(b);            // ... and the forward pipeline shades forward
  SetupTransparent(b);   // blended surfaces over the opaque colour, without depth writes
  SetupMotion(b);        // taa: what animated geometry moved, before TAA reprojects
  SetupTaa(b);
  SetupExposure(b);      // before bloom: bloom's threshold is in exposed units
  SetupBloom(b);
  SetupTonemap(b);
  SetupFxaa(b);
  SetupReadback(b);
  return std::move(b).Build();
}

}  // namespace tessera
