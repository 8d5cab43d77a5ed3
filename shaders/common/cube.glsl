// Cube map addressing shared by the IBL compute shaders (they write cube faces through an
// image2DArray, one layer per face, and must put every texel where a samplerCube lookup will look
// for it). renderer/ibl.cpp has the same mapping on the CPU (CubeDirection); keep the two in step.
//
// Faces are the layers 0..5 = +X, -X, +Y, -Y, +Z, -Z. The Vulkan spec ("Cube Map Face
// Selection") picks the face by the major axis ma of the direction r and then
//   s = (sc / |ma| + 1) / 2,   t = (tc / |ma| + 1) / 2
// with (sc, tc) per face:
//   +X: (-rz, -ry)   -X: (+rz, -ry)   +Y: (+rx, +rz)   -Y: (+rx, -rz)   +Z: (+rx, -ry)
//   -Z: (-rx, -ry)
// s runs along the image's x (columns), t along its y (rows). CubeDirection inverts this: with
// a = 2s - 1 and b = 2t - 1 (both sc/|ma| and tc/|ma|) and |ma| = 1, e.g. on +X: rx = 1,
// rz = -a, ry = -b.
#ifndef TESSERA_CUBE_GLSL
#define TESSERA_CUBE_GLSL

// The unit direction through the point `uv` (in [0, 1]^2: (s, t) above, e.g. a texel centre
// (x + 0.5) / size) of cube face `face` (0..5 = +X, -X, +Y, -Y, +Z, -Z).
vec3 CubeDirection(uint face, vec2 uv) {
  float a = uv.x * 2.0 - 1.0;  // sc / |ma|
  float b = uv.y * 2.0 - 1.0;  // tc / |ma|
  vec3 d;
  switch (face) {
    case 0u: d = vec3(1.0, -b, -a); break;   // +X: sc = -rz, tc = -ry
    case 1u: d = vec3(-1.0, -b, a); break;   // -X: sc = +rz, tc = -ry
    case 2u: d = vec3(a, 1.0, b); break;     // +Y: sc = +rx, tc = +rz
    case 3u: d = vec3(a, -1.0, -b); break;   // -Y: sc = +rx, tc = -rz
    case 4u: d = vec3(a, -b, 1.0); break;    // +Z: sc = +rx, tc = -ry
    default: d = vec3(-a, -b, -1.0); break;  // -Z: sc = -rx, tc = -ry
  }
  return normalize(d);
}

// The solid angle (steradians) that the rectangle [x0, x1] x [y0, y1] of a cube face subtends,
// in face coordinates (the a, b above: [-1, 1]^2 is the whole face, at distance 1 from the
// centre). The area element of the face seen from the centre is dA / (1 + x^2 + y^2)^1.5, whose
// antiderivative in both x and y is atan(x * y / sqrt(1 + x^2 + y^2)); the rectangle's integral
// is that function's signed sum over its four corners. Exact, so a face's texels sum to 4 pi / 6.
float CubeAreaElement(float x, float y) {
  // atan(x y / r), the same as atan(x y, r) since r > 0: SwiftShader's two-argument atan gets
  // the sign wrong for some negative x y, which blacked out half the irradiance cube.
  return atan(x * y / sqrt(x * x + y * y + 1.0));
}

float CubeRectSolidAngle(float x0, float y0, float x1, float y1) {
  return CubeAreaElement(x0, y0) - CubeAreaElement(x0, y1) - CubeAreaElement(x1, y0) +
         CubeAreaElement(x1, y1);
}
#endif
