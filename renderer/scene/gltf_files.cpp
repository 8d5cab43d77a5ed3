// LoadGltfSourceFromDisk: gathers a .gltf/.glb and the files its URIs name into a GltfSource.
// Only for trusted local tools, but URIs are still kept inside the asset's directory so a file
// cannot pull arbitrary paths into an upload.
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "renderer/scene/gltf_import.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;

absl::StatusOr<std::vector<uint8_t>> ReadFile(const fs::path& path) {
  std::error_code ec;
  if (fs::exists(path, ec) && !fs::is_regular_file(path, ec)) {  // a directory, a pipe, a device
    return absl::InvalidArgumentError(absl::StrCat(path.string(), ": not a regular file"));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(path.string(), ": cannot open file"));
  std::vector<uint8_t> data;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) return absl::InvalidArgumentError(absl::StrCat(path.string(), ": cannot read"));
  in.seekg(0, std::ios::beg);
  data.resize(static_cast<size_t>(size));
  if (size > 0 && !in.read(reinterpret_cast<char*>(data.data()), size)) {
    return absl::InvalidArgumentError(absl::StrCat(path.string(), ": read error"));
  }
  return data;
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// RFC 3986 %-decoding (the same as the importer's: '+' stays '+').
std::string PercentDecode(std::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && HexValue(s[i + 1]) >= 0 && HexValue(s[i + 2]) >= 0) {
      out += static_cast<char>(HexValue(s[i + 1]) * 16 + HexValue(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// A relative path that stays below the asset directory: no root, no '..', no scheme.
bool IsSafeRelative(const std::string& p) {
  if (p.empty() || p[0] == '/' || p.find('\\') != std::string::npos ||
      p.find('\0') != std::string::npos || p.find(':') != std::string::npos) {
    return false;
  }
  size_t start = 0;
  while (start <= p.size()) {
    size_t end = p.find('/', start);
    if (end == std::string::npos) end = p.size();
    if (p.compare(start, end - start, "..") == 0 && end - start == 2) return false;
    start = end + 1;
  }
  return true;
}

// The JSON text of a .glb (first chunk), or empty when the container is malformed: the
// importer reports that properly, so here it only means "no external files to fetch".
std::string_view GlbJson(const std::vector<uint8_t>& d) {
  if (d.size() < 20) return {};
  uint32_t len = 0, type = 0;
  std::memcpy(&len, &d[12], 4);  // GLB is little-endian, as are the hosts we build for
  std::memcpy(&type, &d[16], 4);
  if (type != 0x4E4F534Au || len > d.size() - 20) return {};
  return std::string_view(reinterpret_cast<const char*>(&d[20]), len);
}

// A directory stands for the one .gltf or .glb file in it (how a multi-file glTF is usually
// handed over); any other path for itself.
absl::StatusOr<fs::path> AssetFile(const std::string& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) return fs::path(path);
  std::vector<fs::path> found;
  for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) {
    std::string ext = it->path().extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if ((ext == ".gltf" || ext == ".glb") && it->is_regular_file(ec)) found.push_back(it->path());
  }
  if (ec) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": cannot list the directory: ", ec.message()));
  }
  if (found.empty()) {
    return absl::NotFoundError(
        absl::StrCat(path, ": a directory without a .gltf or .glb file in it"));
  }
  if (found.size() > 1) {
    std::sort(found.begin(), found.end());
    std::string names;
    for (const fs::path& f : found)
      absl::StrAppend(&names, names.empty() ? "" : ", ", f.filename().string());
    return absl::InvalidArgumentError(absl::StrCat(path, ": a directory with ", found.size(),
                                                   " glTF files (", names,
                                                   "); name the one to use"));
  }
  return found[0];
}

}  // namespace

absl::StatusOr<GltfSource> LoadGltfSourceFromDisk(const std::string& asset_path) {
  ASSIGN_OR_RETURN(const fs::path file, AssetFile(asset_path));
  const std::string path = file.string();
  ASSIGN_OR_RETURN(std::vector<uint8_t> main, ReadFile(path));
  GltfSource source;
  source.main_file = file.filename().string();
  const bool is_glb = main.size() >= 4 && std::memcmp(main.data(), "glTF", 4) == 0;
  const std::string_view text =
      is_glb ? GlbJson(main)
             : std::string_view(reinterpret_cast<const char*>(main.data()), main.size());
  source.files[source.main_file] = std::move(main);

  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text.begin(), text.end());
  } catch (const std::exception&) {
    return source;  // ImportGltf gives the precise JSON error
  }
  if (!j.is_object()) return source;

  std::map<std::string, std::string> uris;  // uri -> the first field that names it
  for (const char* array : {"buffers", "images"}) {
    auto it = j.find(array);
    if (it == j.end() || !it->is_array()) continue;
    for (size_t i = 0; i < it->size(); ++i) {
      const nlohmann::json& item = (*it)[i];
      if (!item.is_object()) continue;
      auto uri = item.find("uri");
      if (uri == item.end() || !uri->is_string()) continue;
      const std::string u = uri->get<std::string>();
      if (u.rfind("data:", 0) != 0) uris.emplace(u, absl::StrCat(array, "[", i, "].uri"));
    }
  }
  const fs::path dir = file.parent_path();
  for (const auto& [uri, field] : uris) {
    const std::string key = PercentDecode(uri);
    if (!IsSafeRelative(key)) {
      return absl::InvalidArgumentError(absl::StrCat(
          path, ": ", field, " '", uri, "' is absolute or leaves the asset directory"));
    }
    if (source.files.count(key)) continue;
    absl::StatusOr<std::vector<uint8_t>> bytes = ReadFile(dir / key);
    if (!bytes.ok()) {
      return absl::Status(bytes.status().code(),
                          absl::StrCat(path, ": ", field, " '", uri, "': ",
                                       bytes.status().message(),
                                       " (the files a .gltf names must be where it says)"));
    }
    source.files[key] = *std::move(bytes);
  }
  return source;
}

}  // namespace tessera
