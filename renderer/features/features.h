#pragma once
// The frame's features. Each effect lives in one file of renderer/features/ with
//   Setup(GraphBuilder&)  declaring the passes it adds for the frame's settings and what each
//                         reads and writes (the graph derives the barriers),
//   Prepare(...)          its uniforms and per-frame data (where it has any), and
//   the Pass that records its commands (features/pass.h).
// PlanFrame (frame.cpp) calls the Setups in the frame's order.
#include "renderer/graph/frame_graph.h"

namespace tessera {

// skinning.cpp: an animated scene's new pose (drawable records, skinned and morphed vertices).
void SetupSkinning(GraphBuilder& b);
// culling.cpp: gpu_frustum / gpu_occlusion's first culling phase.
void SetupCulling(GraphBuilder& b);
// culling.cpp: gpu_occlusion's second phase: the depth pyramid of what the first phase drew,
// the other drawables tested against it, and the depth (or visibility) of those now visible.
void SetupOcclusion(GraphBuilder& b);
// depth_prepass.cpp: depth of the opaque and alpha-mask geometry (vis_mlaa: its visibility
// pass, which is its depth pass). `late`: the second gpu_occlusion phase.
void SetupDepth(GraphBuilder& b);
void AddDepthPass(GraphBuilder& b, bool late);
// vis_mlaa.cpp: the visibility ids (phase 0 or the late phase; multisampled for vis_mlaa), and
// vis_mlaa's resolve (its shading is SetupVisibilityShading's) and geometric AA.
void AddVisibilityPass(GraphBuilder& b, bool late);
void SetupVisMlaa(GraphBuilder& b);
void SetupGeometricAa(GraphBuilder& b);
// vis_shade.cpp: the shading of the visibility pipeline and of vis_mlaa: each pixel's material
// (or the sky), then one compute dispatch per material over its pixels.
void SetupVisibilityShading(GraphBuilder& b);
// forward_plus.cpp: per-tile light lists from the depth.
void SetupLightCulling(GraphBuilder& b);
// shadows.cpp: the atlas faces whose view changed (the atlas lives outside the graph).
void SetupShadows(GraphBuilder& b);
// ssao.cpp: obscurance from the depth, blurred.
void SetupSsao(GraphBuilder& b);
// forward.cpp: PBR shading against the prepass depth (every mode but vis_mlaa), and the
// blended surfaces back to front over the opaque result.
void SetupForward(GraphBuilder& b);
void SetupTransparent(GraphBuilder& b);
// motion.cpp: taa's object motion where animated geometry moved since the view's last frame.
void SetupMotion(GraphBuilder& b);
// post.cpp: taa, tonemap, fxaa.
void SetupTaa(GraphBuilder& b);
void SetupTonemap(GraphBuilder& b);
void SetupFxaa(GraphBuilder& b);
// exposure.cpp: auto exposure's average log luma, adapted per view.
void SetupExposure(GraphBuilder& b);
// bloom.cpp: soft threshold, downsample and upsample chains.
void SetupBloom(GraphBuilder& b);
// readback.cpp: the final image to the host.
void SetupReadback(GraphBuilder& b);

}  // namespace tessera
