// vis_mlaa's runner-up surfaces (vis_resolve.comp): the word of a pixel's runner-up record.
#ifndef TESSERA_RUNNER_UP_GLSL
#define TESSERA_RUNNER_UP_GLSL
// A runner-up surface's word (vis_resolve.comp; the record's other word is the id to shade):
// bits 0-7 its samples, 8-17 and 18-27 their mean position (x, y; 10-bit fixed point over
// [0, 1]), 28-31 where its colour comes from: neighbour 0-7 (kNeighbours below)
// shows it, kRunnerUpShaded: shaded here, kRunnerUpUndecided: before kResolveRunnerUps.
const uint kRunnerUpShaded = 8u;
const uint kRunnerUpUndecided = 15u;
uint PackRunnerUp(uint mask, vec2 mean, uint source) {
  uvec2 q = uvec2(clamp(mean, 0.0, 1.0) * 1023.0 + 0.5);
  return (mask & 0xffu) | (q.x << 8) | (q.y << 18) | (source << 28);
}
vec2 RunnerUpMean(uint word) { return vec2((word >> 8) & 0x3ffu, (word >> 18) & 0x3ffu) / 1023.0; }
uint RunnerUpSource(uint word) { return word >> 28; }

// The 8 neighbours by angle, counter-clockwise from +x in framebuffer coordinates (y down): the
// runner-up's sources, and geometric AA's compass directions.
const ivec2 kNeighbours[8] = ivec2[8](ivec2(1, 0), ivec2(1, 1), ivec2(0, 1), ivec2(-1, 1),
                                      ivec2(-1, 0), ivec2(-1, -1), ivec2(0, -1), ivec2(1, -1));
#endif
