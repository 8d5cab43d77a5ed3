// tinygltf's implementation, compiled into tessera_scene from Debian's header in its default
// configuration (as Debian's libtinygltf.so is built), with the stb_image it calls, instead of
// linked from libtinygltf.so and libstb.so. Debian's Draco carries another tinygltf, a
// different version, for its glTF transcoder: libdraco.so exports its symbols and libdraco.a has them in
// tiny_gltf_utils.cc.o. With libtinygltf.so, whichever of the two the linker or the loader met
// first served the importer's calls, and the wrong one corrupted memory. Defined here, the
// archive pass over tessera_scene resolves them (and stb_image's, which tiny_gltf_utils.cc.o
// also defines) before libdraco.a is searched, and the executable's definitions win over any
// shared library's. The importer decodes images with libpng and TurboJPEG, never stb_image.
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_INCLUDE_STB_IMAGE
#define TINYGLTF_NO_INCLUDE_STB_IMAGE_WRITE
#include <tiny_gltf.h>
