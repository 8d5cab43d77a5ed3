#pragma once
// The built-in demo scene, generated in code (no file needed): the default scene of the
// render tool and the daemon.
#include "renderer/scene/cpu_scene.h"

namespace tessera {

// Builds the demo scene: PBR objects (polished metals, rough dielectrics, a textured and a
// normal-mapped object, one alpha-masked and one blended object) on a textured floor, lit by
// a few coloured point/spot lights and a sun. Deterministic: the same bytes every call.
CpuScene BuildDemoScene();

}  // namespace tessera
