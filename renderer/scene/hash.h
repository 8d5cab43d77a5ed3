#pragma once
// A 32-bit integer hash ("lowbias32", Chris Wellons): the deterministic randomness of generated
// content (synthetic lights, the city scene) gives the same numbers on every platform and
// standard library, unlike the std distributions.
#include <cstdint>

namespace tessera {

inline uint32_t Lowbias32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

}  // namespace tessera
