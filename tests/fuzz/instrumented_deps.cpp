// Fuzz builds only: tinygltf and stb_image compiled from their Debian headers in this program,
// so that they are instrumented too (coverage guidance and ASan checks inside the parsers).
// The executable's definitions take precedence over libtinygltf.so and libstb.so, which were
// built without instrumentation; the configuration is the headers' default, as Debian's.
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_INCLUDE_STB_IMAGE
#define TINYGLTF_NO_INCLUDE_STB_IMAGE_WRITE
#include <tiny_gltf.h>
