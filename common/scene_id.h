#pragma once
// The content hash that names an uploaded scene (SceneInfo.scene_id in scene.proto). Shared by
// the server and the clients, so a client can ask HasScene before uploading.
#include <cstdint>
#include <map>
#include <string>
#include <string_view>

namespace tessera {

// Lowercase hex SHA-256 of `data`.
std::string Sha256Hex(const void* data, size_t size);

// Incremental SHA-256 (for uploads that arrive in chunks).
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void Update(const void* data, size_t size);
  std::string FinishHex();  // once

 private:
  void* ctx_;  // EVP_MD_CTX
};

// sha256 of: for every file sorted by name, name "\n" sha256hex "\n"; then "main " main "\n".
// `file_sha256` maps file name -> lowercase hex SHA-256 of its content.
std::string SceneId(const std::map<std::string, std::string>& file_sha256,
                    std::string_view main_file);

// True for 64 lowercase hex characters.
bool IsSha256Hex(std::string_view s);

}  // namespace tessera
