#include "server/auth.h"

#include <openssl/rand.h>

#include <openssl/crypto.h>
#include <openssl/evp.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <limits>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace tessera::server {

std::string RandomHex(size_t bytes) {
  std::vector<unsigned char> raw(bytes);
  if (RAND_bytes(raw.data(), static_cast<int>(raw.size())) != 1) std::abort();
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes * 2);
  for (unsigned char b : raw) {
    out.push_back(kHex[b >> 4]);
    out.push_back(kHex[b & 15]);
  }
  return out;
}
namespace {

// Debian's Abseil is built with its own string_view (ABSL_OPTION_USE_STD_STRING_VIEW 0), so
// std::string_view must be converted to pass it to absl::StrCat and friends.
absl::string_view Absl(std::string_view s) { return absl::string_view(s.data(), s.size()); }

constexpr std::string_view kLineFormat =
    "expected \"<token> <name> [max_sessions=N] [max_uploads=N]\"";

// Error messages quote a field only when it cannot be a token. A token in the wrong column
// (say, two tokens on one line) is at least kMinTokenLength long, so longer fields are
// described by length instead of quoted.
std::string Quote(std::string_view field) {
  if (field.size() < kMinTokenLength)
    return absl::StrCat("\"", absl::CHexEscape(Absl(field)), "\"");
  return absl::StrCat("(a ", field.size(), "-character value, not shown)");
}

absl::Status CheckToken(std::string_view token) {
  if (token.size() < kMinTokenLength)
    return absl::InvalidArgumentError(
        absl::StrCat("token is ", token.size(), " characters; at least ", kMinTokenLength,
                     " are required (a short token is easy to guess)"));
  if (token.size() > kMaxTokenLength)
    return absl::InvalidArgumentError(
        absl::StrCat("token is longer than ", kMaxTokenLength, " characters"));
  for (char c : token) {
    // Fields are split at spaces and tabs already; this catches other control bytes and
    // non-ASCII text, which clients could not send reliably in a header.
    if (c < 0x21 || c > 0x7e)
      return absl::InvalidArgumentError("token has a character that is not printable ASCII");
  }
  return absl::OkStatus();
}

bool IsNameChar(char c) { return absl::ascii_isalnum(c) || c == '_' || c == '.' || c == '-'; }

absl::Status CheckName(std::string_view name) {
  bool ok = !name.empty() && name.size() <= kMaxPrincipalNameLength;
  for (char c : name) ok = ok && IsNameChar(c);
  if (ok) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat("name ", Quote(name), " must be 1 to ",
                                                 kMaxPrincipalNameLength,
                                                 " characters of A-Z a-z 0-9 _ . -"));
}

// A plain decimal uint32. from_chars already refuses signs, spaces and "0x"; the checks
// below refuse trailing junk ("4x") and values that do not fit.
std::optional<uint32_t> ParseLimit(std::string_view value) {
  uint32_t out = 0;
  const char* end = value.data() + value.size();
  auto [ptr, ec] = std::from_chars(value.data(), end, out);
  if (value.empty() || ec != std::errc() || ptr != end) return std::nullopt;
  return out;
}

// Applies one "key=value" field to `p`.
absl::Status ApplyOption(std::string_view field, Principal* p) {
  const size_t eq = field.find('=');
  if (eq == std::string_view::npos)
    return absl::InvalidArgumentError(
        absl::StrCat("option ", Quote(field), " is not key=value; ", Absl(kLineFormat)));
  const std::string_view key = field.substr(0, eq), value = field.substr(eq + 1);
  std::optional<uint32_t>* slot = key == "max_sessions"  ? &p->max_sessions
                                  : key == "max_uploads" ? &p->max_uploads
                                                         : nullptr;
  if (slot == nullptr)
    return absl::InvalidArgumentError(
        absl::StrCat("unknown option ", Quote(key), " (known: max_sessions, max_uploads)"));
  if (slot->has_value())
    return absl::InvalidArgumentError(absl::StrCat(Absl(key), " is given twice"));
  *slot = ParseLimit(value);
  if (!slot->has_value())
    return absl::InvalidArgumentError(absl::StrCat(Absl(key), ": ", Quote(value),
                                                   " is not an unsigned integer up to ",
                                                   std::numeric_limits<uint32_t>::max()));
  return absl::OkStatus();
}

// The principal of one non-comment line; the token is fields[0].
absl::StatusOr<Principal> ParseFields(const std::vector<std::string_view>& fields) {
  if (absl::Status s = CheckToken(fields[0]); !s.ok()) return s;
  if (fields.size() < 2)
    return absl::InvalidArgumentError(absl::StrCat("missing name; ", Absl(kLineFormat)));
  if (absl::Status s = CheckName(fields[1]); !s.ok()) return s;
  Principal p;
  p.name = std::string(fields[1]);
  for (size_t i = 2; i < fields.size(); ++i) {
    if (absl::Status s = ApplyOption(fields[i], &p); !s.ok()) return s;
  }
  return p;
}

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

// Fields are separated by runs of spaces and tabs.
std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t i = 0;
  while (i < line.size()) {
    if (IsBlank(line[i])) {
      ++i;
      continue;
    }
    size_t end = i;
    while (end < line.size() && !IsBlank(line[end])) ++end;
    fields.push_back(line.substr(i, end - i));
    i = end;
  }
  return fields;
}

std::vector<std::string_view> SplitLines(std::string_view text) {
  std::vector<std::string_view> lines;
  for (size_t start = 0; start <= text.size();) {
    size_t end = std::min(text.find('\n', start), text.size());
    lines.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return lines;
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && absl::ascii_isspace(s.front())) s.remove_prefix(1);
  while (!s.empty() && absl::ascii_isspace(s.back())) s.remove_suffix(1);  // also CRLF's '\r'
  return s;
}

absl::StatusOr<std::string> ReadFile(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (f == nullptr) return absl::ErrnoToStatus(errno, absl::StrCat("token file ", path));
  std::string text;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f.get())) > 0) text.append(buf, n);
  const int error = errno;
  OPENSSL_cleanse(buf, sizeof buf);
  // A directory opens fine and fails here (EISDIR).
  if (std::ferror(f.get())) return absl::ErrnoToStatus(error, absl::StrCat("token file ", path));
  return text;
}

// One message for a wrong scheme and an unknown token alike, so a caller learns nothing about
// why it was refused.
absl::Status InvalidBearerToken() { return absl::UnauthenticatedError("invalid bearer token"); }

const std::shared_ptr<const Principal>& Anonymous() {
  // Leaked on purpose: gRPC threads may still authenticate while statics are destroyed.
  static const auto* anonymous =
      new std::shared_ptr<const Principal>(std::make_shared<Principal>());
  return *anonymous;
}

}  // namespace

std::optional<TokenTable::Digest> TokenTable::Hash(std::string_view token) {
  Digest d;
  unsigned int len = 0;
  if (EVP_Digest(token.data(), token.size(), d.data(), &len, EVP_sha256(), nullptr) != 1 ||
      len != d.size())
    return std::nullopt;
  return d;
}

absl::StatusOr<TokenTable> TokenTable::Parse(std::string_view text, std::string_view file_name) {
  TokenTable table;
  std::map<std::string, int, std::less<>> names;  // name -> line, for duplicates
  const std::vector<std::string_view> lines = SplitLines(text);
  for (size_t i = 0; i < lines.size(); ++i) {
    const int line_no = static_cast<int>(i) + 1;
    const std::string_view line = Trim(lines[i]);
    if (line.empty() || line.front() == '#') continue;
    auto fail = [&](absl::string_view what) {
      return absl::InvalidArgumentError(absl::StrCat(Absl(file_name), ":", line_no, ": ", what));
    };
    const std::vector<std::string_view> fields = SplitFields(line);
    absl::StatusOr<Principal> p = ParseFields(fields);
    if (!p.ok()) return fail(p.status().message());
    const std::optional<Digest> digest = Hash(fields[0]);
    if (!digest) return absl::InternalError(fail("SHA-256 failed").message());
    for (const Entry& e : table.entries_) {
      if (e.digest == *digest)
        return fail(absl::StrCat("duplicate token (the same as \"", e.principal.name, "\" on line ",
                                 e.line, ")"));
    }
    if (auto [it, inserted] = names.emplace(p->name, line_no); !inserted)
      return fail(absl::StrCat("duplicate name \"", p->name, "\" (also on line ", it->second,
                               "); each name must be unique"));
    table.entries_.push_back(Entry{*digest, *std::move(p), line_no});
  }
  if (table.entries_.empty())
    return absl::InvalidArgumentError(
        absl::StrCat(Absl(file_name),
                     ": no tokens (a server with a token file but no tokens would refuse every "
                     "call; add \"<token> <name>\" lines)"));
  return table;
}

absl::StatusOr<TokenTable> TokenTable::Load(const std::string& path) {
  absl::StatusOr<std::string> text = ReadFile(path);
  if (!text.ok()) return text.status();
  absl::StatusOr<TokenTable> table = Parse(*text, path);
  // The file is all secrets: wipe our copy (best effort; the reads' reallocations may
  // have left others).
  OPENSSL_cleanse(text->data(), text->size());
  return table;
}

const Principal* TokenTable::Find(std::string_view token) const {
  const std::optional<Digest> digest = Hash(token);
  if (!digest) return nullptr;  // never let a failed hash match anything
  const Principal* found = nullptr;
  for (const Entry& e : entries_) {
    // No early exit: the time must not depend on which entry, if any, matched.
    if (CRYPTO_memcmp(e.digest.data(), digest->data(), digest->size()) == 0) found = &e.principal;
  }
  return found;
}

// ---------------------------------------------------------------------------------------------
// Authenticator

Authenticator::Authenticator() = default;

Authenticator::Authenticator(std::string path, std::shared_ptr<const TokenTable> table)
    : path_(std::move(path)), table_(std::move(table)) {}

absl::StatusOr<std::unique_ptr<Authenticator>> Authenticator::FromFile(const std::string& path) {
  if (path.empty()) return absl::InvalidArgumentError("token file: the path is empty");
  absl::StatusOr<TokenTable> table = TokenTable::Load(path);
  if (!table.ok()) return table.status();
  return std::unique_ptr<Authenticator>(
      new Authenticator(path, std::make_shared<const TokenTable>(*std::move(table))));
}

std::shared_ptr<const TokenTable> Authenticator::table() const {
  std::lock_guard lock(mu_);
  return table_;
}

absl::Status Authenticator::Reload() {
  if (!enabled()) return absl::OkStatus();
  absl::StatusOr<TokenTable> loaded = TokenTable::Load(path_);
  if (!loaded.ok()) return loaded.status();
  auto fresh = std::make_shared<const TokenTable>(*std::move(loaded));
  std::lock_guard lock(mu_);
  table_.swap(fresh);
  return absl::OkStatus();  // the old table goes when its last principal does
}

absl::StatusOr<std::shared_ptr<const Principal>> Authenticator::Authenticate(
    std::string_view authorization) const {
  if (!enabled()) return Anonymous();
  if (authorization.empty())
    return absl::UnauthenticatedError("missing bearer token (authorization: Bearer <token>)");
  constexpr std::string_view kScheme = "bearer ";  // RFC 6750; the scheme is case-insensitive
  if (!absl::StartsWithIgnoreCase(Absl(authorization), Absl(kScheme))) return InvalidBearerToken();
  std::shared_ptr<const TokenTable> t = table();
  const Principal* p = t->Find(authorization.substr(kScheme.size()));
  if (p == nullptr) return InvalidBearerToken();
  // Aliasing constructor: the principal keeps its whole table alive, so a reload never
  // invalidates it.
  return std::shared_ptr<const Principal>(std::move(t), p);
}

size_t Authenticator::token_count() const {
  if (!enabled()) return 0;
  return table()->size();
}

// ---------------------------------------------------------------------------------------------
// UsageCounter

bool UsageCounter::TryAcquire(const std::string& name, std::optional<uint32_t> limit) {
  std::lock_guard lock(mu_);
  auto it = counts_.find(name);
  const uint32_t held = it == counts_.end() ? 0 : it->second;
  // Unlimited still stops at UINT32_MAX rather than wrapping around.
  if (held >= limit.value_or(std::numeric_limits<uint32_t>::max())) return false;
  ++counts_[name];
  return true;
}

void UsageCounter::Release(const std::string& name) {
  std::lock_guard lock(mu_);
  auto it = counts_.find(name);
  if (it == counts_.end()) return;  // unbalanced Release: ignore rather than wrap around
  if (--it->second == 0) counts_.erase(it);
}

uint32_t UsageCounter::count(const std::string& name) const {
  std::lock_guard lock(mu_);
  auto it = counts_.find(name);
  return it == counts_.end() ? 0 : it->second;
}

}  // namespace tessera::server
