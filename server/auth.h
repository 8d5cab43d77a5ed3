#pragma once
// Bearer-token authentication for tesserad (--token_file). Without a token file the server is
// open and every request comes from the anonymous principal.
//
// Token file format:
//
//   # comments and blank lines are ignored
//   # <token> <name> [max_sessions=N] [max_uploads=N]
//   s3cr3t-ops-token-0123456789   ops
//   viewer-token-abcdefghijklmno  viewer   max_sessions=4 max_uploads=0
//
// - Fields are separated by spaces or tabs; a line whose first non-blank character is '#' is a
//   comment (only whole lines: '#' may be part of a token). CRLF line ends are accepted.
// - token: 16 to 256 printable ASCII characters (no spaces). Shorter tokens are refused as
//   too easy to guess. Each token must be unique.
// - name: 1 to 64 characters of A-Z a-z 0-9 _ . - ; unique. It names the client in logs and
//   errors and is the key for per-client limits, so a client may hold several names' tokens
//   but each token belongs to exactly one name.
// - max_sessions / max_uploads: optional unsigned decimal limits on the Stream sessions and
//   uploads this name may have open at once; absent means unlimited (std::nullopt). 0 is
//   allowed and forbids that kind of call (e.g. a view-only client: max_uploads=0). These
//   apply in addition to the server-wide limits in ServerOptions.
// - Any error (malformed line, unknown option, duplicate token or name, short token, or a
//   file without tokens) is INVALID_ARGUMENT "<file>:<line>: <what>". Messages and logs never
//   contain a token: it is a secret. Names are not.
//
// Clients send "authorization: Bearer <token>" metadata on every call. SIGHUP re-reads the
// file (Authenticator::Reload); calls in flight keep the principal they started with.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace tessera::server {

// `bytes` random bytes from the OS's CSPRNG as lower-case hex: ids and tokens nobody can guess
// from another (resume tokens, job ids). Aborts when there is no entropy (nothing safe to do).
std::string RandomHex(size_t bytes);

inline constexpr size_t kMinTokenLength = 16;
inline constexpr size_t kMaxTokenLength = 256;
inline constexpr size_t kMaxPrincipalNameLength = 64;

// Who a request is from.
struct Principal {
  std::string name;                      // "" when auth is off (anonymous)
  std::optional<uint32_t> max_sessions;  // nullopt: unlimited
  std::optional<uint32_t> max_uploads;   // nullopt: unlimited
};

// The parsed token file. Immutable after Parse; stores SHA-256 digests, not the tokens.
class TokenTable {
 public:
  // `file_name` only prefixes error messages ("tokens.txt:3: ...").
  static absl::StatusOr<TokenTable> Parse(std::string_view text, std::string_view file_name);
  // Reads `path` (NOT_FOUND, PERMISSION_DENIED, ... naming it), then Parse.
  static absl::StatusOr<TokenTable> Load(const std::string& path);

  // The principal whose token is `token`, or nullptr. Compares SHA-256 digests with
  // CRYPTO_memcmp against every entry, so the time taken does not reveal how much of a token
  // matched (hashing first also hides the token's length).
  const Principal* Find(std::string_view token) const;
  size_t size() const { return entries_.size(); }

 private:
  using Digest = std::array<unsigned char, 32>;
  struct Entry {
    Digest digest;
    Principal principal;
    int line = 0;  // for "duplicate token" errors
  };
  TokenTable() = default;
  static std::optional<Digest> Hash(std::string_view token);  // nullopt: OpenSSL failed
  std::vector<Entry> entries_;
};

// The token table in use, shared by gRPC's threads. Thread-safe.
class Authenticator {
 public:
  Authenticator();  // auth off: everyone is the anonymous principal
  static absl::StatusOr<std::unique_ptr<Authenticator>> FromFile(const std::string& path);
  Authenticator(const Authenticator&) = delete;
  Authenticator& operator=(const Authenticator&) = delete;

  bool enabled() const { return !path_.empty(); }

  // Re-reads the file given to FromFile and swaps the new table in at once. On error the old
  // table stays in use and the error is returned (a typo must not lock every client out).
  // OK and nothing to do when auth is off.
  absl::Status Reload();

  // `authorization` is the raw "authorization" metadata value ("" when absent). Off: the
  // anonymous principal. On: "Bearer <token>" (scheme in any case, one space) gives that
  // token's principal; the pointer keeps it alive across reloads. Otherwise UNAUTHENTICATED:
  // "missing bearer token ..." when the header is absent, "invalid bearer token" for another
  // scheme or an unknown token (deliberately not saying which).
  absl::StatusOr<std::shared_ptr<const Principal>> Authenticate(
      std::string_view authorization) const;

  size_t token_count() const;  // 0 when off

 private:
  Authenticator(std::string path, std::shared_ptr<const TokenTable> table);
  std::shared_ptr<const TokenTable> table() const;

  const std::string path_;  // empty: auth off
  mutable std::mutex mu_;   // guards table_ (the pointer, not the immutable table)
  std::shared_ptr<const TokenTable> table_;
};

// Sessions or uploads open per principal name, for the per-principal limits. Thread-safe.
// Use one counter per kind of resource.
class UsageCounter {
 public:
  // Takes one unit for `name` if it holds fewer than `limit` (nullopt: unlimited); returns
  // false, taking nothing, when at the limit.
  bool TryAcquire(const std::string& name, std::optional<uint32_t> limit);
  // Gives back one unit taken by TryAcquire.
  void Release(const std::string& name);
  uint32_t count(const std::string& name) const;

 private:
  mutable std::mutex mu_;
  std::map<std::string, uint32_t> counts_;  // names holding nothing are erased
};

}  // namespace tessera::server
