#pragma once
// Assembles an UploadScene stream into a glTF file set, checking every message against the
// manifest and the server limits before its bytes are stored. Pure logic (no gRPC calls),
// so it is unit-tested directly. Not thread-safe: one per upload stream.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/scene/gltf_import.h"
#include "common/scene_id.h"
#include "tessera/v1/scene.pb.h"

namespace tessera::server {

struct UploadLimits {
  uint64_t max_bytes = 1ull << 30;
  uint32_t max_files = 1024;
  uint32_t max_chunk_bytes = 1u << 20;
};

// INVALID_ARGUMENT unless `name` is a relative '/'-separated path without empty, "." or ".."
// segments, backslashes or control characters, at most 1024 bytes.
absl::Status ValidateUploadName(const std::string& name);

class UploadAssembler {
 public:
  explicit UploadAssembler(const UploadLimits& limits) : limits_(limits) {}

  // The first message. INVALID_ARGUMENT (bad name, duplicate, no main file, bad sha256 text)
  // or RESOURCE_EXHAUSTED (max_upload_files, max_upload_bytes) naming the limit.
  absl::Status Begin(const v1::UploadManifest& manifest);
  bool begun() const { return !files_.empty(); }

  // A data chunk; its bytes are moved out of `chunk`. INVALID_ARGUMENT for an unknown file
  // index, an out-of-order offset, an empty or oversize chunk, or data past the declared size.
  absl::Status Add(v1::UploadChunk* chunk);

  // After the client's last message: every file complete (INVALID_ARGUMENT naming the first
  // short file) and matching its sha256 (DATA_LOSS). Returns the file set; `scene_id` receives
  // the content hash (see SceneInfo.scene_id).
  absl::StatusOr<GltfSource> Finish(std::string* scene_id);

  uint64_t declared_bytes() const { return declared_bytes_; }
  uint64_t received_bytes() const { return received_bytes_; }
  const std::string& main_file() const { return main_file_; }
  size_t file_count() const { return file_count_; }

 private:
  struct File {
    std::string name;
    uint64_t size = 0;
    std::string expected_sha256;
    std::vector<uint8_t> data;
    std::unique_ptr<Sha256> hash;
  };
  UploadLimits limits_;
  std::vector<File> files_;
  std::string main_file_;
  size_t file_count_ = 0;
  uint64_t declared_bytes_ = 0;
  uint64_t received_bytes_ = 0;
};

}  // namespace tessera::server
