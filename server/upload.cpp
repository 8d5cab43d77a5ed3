#include "server/upload.h"

#include <map>
#include <set>

#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace tessera::server {
namespace {

bool IsGltfName(const std::string& name) {
  return absl::EndsWithIgnoreCase(name, ".gltf") || absl::EndsWithIgnoreCase(name, ".glb");
}

}  // namespace

absl::Status ValidateUploadName(const std::string& name) {
  auto bad = [&](const char* why) {
    return absl::InvalidArgumentError(
        absl::StrCat("file name \"", absl::CHexEscape(name.substr(0, 200)), "\": ", why));
  };
  if (name.empty()) return bad("is empty");
  if (name.size() > 1024) return bad("is longer than 1024 bytes");
  for (unsigned char c : name) {
    if (c < 0x20 || c == 0x7f) return bad("contains a control character");
    if (c == '\\') return bad("contains a backslash (use '/')");
  }
  if (name.front() == '/') return bad("is absolute (names are relative to the glTF)");
  for (absl::string_view seg : absl::StrSplit(name, '/')) {
    if (seg.empty()) return bad("has an empty path segment");
    if (seg == "." || seg == "..") return bad("has a '.' or '..' segment");
  }
  return absl::OkStatus();
}

absl::Status UploadAssembler::Begin(const v1::UploadManifest& m) {
  if (begun()) return absl::InvalidArgumentError("manifest: sent twice");
  if (m.files_size() == 0) return absl::InvalidArgumentError("manifest.files: is empty");
  if (static_cast<uint64_t>(m.files_size()) > limits_.max_files)
    return absl::ResourceExhaustedError(absl::StrCat("manifest.files: ", m.files_size(),
                                                     " files exceed the max_upload_files limit (",
                                                     limits_.max_files, ")"));
  std::set<std::string> names;
  uint64_t total = 0;
  std::vector<std::string> gltf_names;
  for (int i = 0; i < m.files_size(); ++i) {
    const v1::UploadFile& f = m.files(i);
    if (absl::Status st = ValidateUploadName(f.name()); !st.ok())
      return absl::InvalidArgumentError(absl::StrCat("manifest.files[", i, "]: ", st.message()));
    if (!names.insert(f.name()).second)
      return absl::InvalidArgumentError(
          absl::StrCat("manifest.files[", i, "]: duplicate name \"", f.name(), "\""));
    if (!f.sha256().empty() && !IsSha256Hex(f.sha256()))
      return absl::InvalidArgumentError(
          absl::StrCat("manifest.files[", i, "].sha256: must be 64 lowercase hex characters"));
    // Checked one by one, as a difference, so the sum cannot wrap (total <= max_bytes).
    if (f.size() > limits_.max_bytes - total)
      return absl::ResourceExhaustedError(absl::StrCat(
          "manifest.files: ", f.name(), " brings the upload past the max_upload_bytes limit (",
          limits_.max_bytes, " bytes)"));
    total += f.size();
    if (IsGltfName(f.name())) gltf_names.push_back(f.name());
  }
  std::string main = m.main_file();
  if (main.empty()) {
    if (gltf_names.size() != 1)
      return absl::InvalidArgumentError(
          absl::StrCat("manifest.main_file: not given, and the upload has ", gltf_names.size(),
                       " files ending in .gltf or .glb (name the main one)"));
    main = gltf_names.front();
  } else if (!names.count(main)) {
    return absl::InvalidArgumentError(
        absl::StrCat("manifest.main_file: \"", main, "\" is not in manifest.files"));
  } else if (!IsGltfName(main)) {
    return absl::InvalidArgumentError(
        absl::StrCat("manifest.main_file: \"", main, "\" does not end in .gltf or .glb"));
  }
  main_file_ = main;
  file_count_ = m.files_size();
  declared_bytes_ = total;
  files_.reserve(m.files_size());
  for (const v1::UploadFile& f : m.files()) {
    File file;
    file.name = f.name();
    file.size = f.size();
    file.expected_sha256 = f.sha256();
    file.hash = std::make_unique<Sha256>();
    files_.push_back(std::move(file));
  }
  return absl::OkStatus();
}

absl::Status UploadAssembler::Add(v1::UploadChunk* chunk) {
  if (!begun()) return absl::InvalidArgumentError("chunk: the first message must be the manifest");
  if (chunk->file_index() >= files_.size())
    return absl::InvalidArgumentError(absl::StrCat("chunk.file_index: ", chunk->file_index(),
                                                   " but the manifest has ", files_.size(),
                                                   " files"));
  File& f = files_[chunk->file_index()];
  const std::string& data = chunk->data();
  if (data.empty())
    return absl::InvalidArgumentError(absl::StrCat("chunk.data: empty (", f.name, ")"));
  if (data.size() > limits_.max_chunk_bytes)
    return absl::ResourceExhaustedError(absl::StrCat("chunk.data: ", data.size(),
                                                     " bytes exceed the max_chunk_bytes limit (",
                                                     limits_.max_chunk_bytes, ")"));
  if (chunk->offset() != f.data.size())
    return absl::InvalidArgumentError(absl::StrCat("chunk.offset: ", chunk->offset(), " for ",
                                                   f.name, ", expected ", f.data.size(),
                                                   " (chunks of a file come in order)"));
  if (f.data.size() + data.size() > f.size)
    return absl::InvalidArgumentError(
        absl::StrCat("chunk.data: ", f.name, " gets more than its declared ", f.size, " bytes"));
  // Reserve the declared size (within the limits checked in Begin) but at most 64 MiB up
  // front: memory follows the bytes actually received, not what a client claims.
  if (f.data.empty()) f.data.reserve(std::min<uint64_t>(f.size, 64u << 20));
  f.hash->Update(data.data(), data.size());
  f.data.insert(f.data.end(), data.begin(), data.end());
  received_bytes_ += data.size();
  chunk->clear_data();
  return absl::OkStatus();
}

absl::StatusOr<GltfSource> UploadAssembler::Finish(std::string* scene_id) {
  if (!begun()) return absl::InvalidArgumentError("upload: no manifest was sent");
  std::map<std::string, std::string> hashes;
  for (File& f : files_) {
    if (f.data.size() != f.size)
      return absl::InvalidArgumentError(absl::StrCat(f.name, ": received ", f.data.size(),
                                                     " of its declared ", f.size, " bytes"));
    std::string sha = f.hash->FinishHex();
    if (!f.expected_sha256.empty() && sha != f.expected_sha256)
      return absl::DataLossError(
          absl::StrCat(f.name, ": sha256 is ", sha, ", the manifest says ", f.expected_sha256));
    hashes.emplace(f.name, std::move(sha));
  }
  *scene_id = SceneId(hashes, main_file_);
  GltfSource source;
  source.main_file = main_file_;
  for (File& f : files_) source.files.emplace(f.name, std::move(f.data));
  files_.clear();
  return source;
}

}  // namespace tessera::server
