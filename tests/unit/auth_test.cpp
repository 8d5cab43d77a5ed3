// Bearer-token authentication: parsing the token file (every malformed line is reported with
// file:line, and never with the secret token in the message), looking tokens up, the forms of
// the authorization header, reloading the file while other threads authenticate, and the
// per-principal usage counter.
#include "server/auth.h"

#include <gtest/gtest.h>
#include "tests/unit/status_matchers.h"
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace tessera::server {
namespace {

constexpr char kOpsToken[] = "s3cr3t-ops-token-0123456789";
constexpr char kViewerToken[] = "viewer-token-abcdefghijklmno";
constexpr char kSecret[] = "do-not-print-me-0123456789";  // the token on malformed lines

using test::IsError;

// A file under the test's temp dir, removed at the end of the test.
class TempFile {
 public:
  TempFile() {
    static std::atomic<int> counter{0};
    path_ = ::testing::TempDir() + "/tessera_auth_test_" + std::to_string(getpid()) + "_" +
            std::to_string(counter++) + ".txt";
  }
  ~TempFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

  // Writes to a sibling and renames it over the file, so a reader never sees half a file.
  void Write(std::string_view text) const {
    const std::string tmp = path_ + ".new";
    {
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      out << text;
      ASSERT_TRUE(out.good()) << tmp;
    }
    ASSERT_EQ(std::rename(tmp.c_str(), path_.c_str()), 0) << path_;
  }

 private:
  std::string path_;
};

std::string Line(std::string_view token, std::string_view rest) {
  return std::string(token) + " " + std::string(rest) + "\n";
}

// The token file from the header comment.
std::string ExampleFile() {
  return "# comments and blank lines are ignored\n"
         "# <token> <name> [max_sessions=N] [max_uploads=N]\n"
         "s3cr3t-ops-token-0123456789   ops\n"
         "\n"
         "viewer-token-abcdefghijklmno  viewer   max_sessions=4 max_uploads=0\n";
}

std::unique_ptr<Authenticator> AuthFrom(const TempFile& file, std::string_view text) {
  file.Write(text);
  absl::StatusOr<std::unique_ptr<Authenticator>> auth = Authenticator::FromFile(file.path());
  EXPECT_TRUE(auth.ok()) << auth.status();
  return auth.ok() ? *std::move(auth) : nullptr;
}

std::string Bearer(std::string_view token) { return "Bearer " + std::string(token); }

// ---------------------------------------------------------------------------------------------
// TokenTable::Parse

TEST(TokenTableTest, ParsesTheDocumentedExample) {
  absl::StatusOr<TokenTable> table = TokenTable::Parse(ExampleFile(), "tokens.txt");
  ASSERT_TRUE(table.ok()) << table.status();
  EXPECT_EQ(table->size(), 2u);

  const Principal* ops = table->Find(kOpsToken);
  ASSERT_NE(ops, nullptr);
  EXPECT_EQ(ops->name, "ops");
  EXPECT_EQ(ops->max_sessions, std::nullopt);  // absent: unlimited
  EXPECT_EQ(ops->max_uploads, std::nullopt);

  const Principal* viewer = table->Find(kViewerToken);
  ASSERT_NE(viewer, nullptr);
  EXPECT_EQ(viewer->name, "viewer");
  EXPECT_EQ(viewer->max_sessions, 4u);
  EXPECT_EQ(viewer->max_uploads, 0u);  // 0 is a limit (no uploads), not "unlimited"
}

TEST(TokenTableTest, AcceptsTabsIndentationCrlfAndNoFinalNewline) {
  const std::string text = std::string("  # indented comment\r\n") + "\t" + kOpsToken +
                           "\tops\tmax_uploads=4294967295\r\n" + "   \r\n" + kViewerToken +
                           " viewer max_sessions=1";
  absl::StatusOr<TokenTable> table = TokenTable::Parse(text, "tokens.txt");
  ASSERT_TRUE(table.ok()) << table.status();
  ASSERT_NE(table->Find(kOpsToken), nullptr);
  EXPECT_EQ(table->Find(kOpsToken)->max_uploads, 4294967295u);
  ASSERT_NE(table->Find(kViewerToken), nullptr);
  EXPECT_EQ(table->Find(kViewerToken)->max_sessions, 1u);
}

TEST(TokenTableTest, TokenAndNameLengthBoundaries) {
  const std::string shortest(kMinTokenLength, 'a'), longest(kMaxTokenLength, 'b');
  const std::string long_name(kMaxPrincipalNameLength, 'n');
  const std::string text = Line(shortest, "a") + Line(longest, long_name) +
                           Line("~!@#$%^&*()_+{}|:\"<>?`-=[]\\;',./", "Odd_name.v2-x");
  absl::StatusOr<TokenTable> table = TokenTable::Parse(text, "tokens.txt");
  ASSERT_TRUE(table.ok()) << table.status();
  EXPECT_EQ(table->size(), 3u);
  ASSERT_NE(table->Find(longest), nullptr);
  EXPECT_EQ(table->Find(longest)->name, long_name);
  EXPECT_NE(table->Find("~!@#$%^&*()_+{}|:\"<>?`-=[]\\;',./"), nullptr);
}

TEST(TokenTableTest, MalformedLinesNameFileAndLineButNotTheToken) {
  const std::string other_secret = "another-secret-token/0002";  // too long to be echoed
  struct Case {
    std::string line;
    std::vector<std::string_view> needles;
  };
  const std::vector<Case> cases = {
      {kSecret, {"missing name"}},
      {Line(kSecret, "bad/name"), {"name \"bad/name\"", "A-Z a-z 0-9 _ . -"}},
      {Line(kSecret, std::string(65, 'n')), {"name", "1 to 64"}},
      {Line(kSecret, other_secret), {"name", "not shown"}},
      {Line(kSecret, "ops max_sessions"), {"option \"max_sessions\"", "key=value"}},
      {Line(kSecret, "ops " + other_secret), {"option", "not shown", "key=value"}},
      {Line(kSecret, "ops max_session=3"), {"unknown option \"max_session\"", "max_uploads"}},
      {Line(kSecret, "ops " + other_secret + "=1"), {"unknown option", "not shown"}},
      {Line(kSecret, "ops max_sessions=-1"), {"max_sessions: \"-1\"", "unsigned integer"}},
      {Line(kSecret, "ops max_sessions=+1"), {"max_sessions", "unsigned integer"}},
      {Line(kSecret, "ops max_uploads=4294967296"), {"max_uploads", "4294967295"}},
      {Line(kSecret, "ops max_uploads=0x10"), {"max_uploads", "unsigned integer"}},
      {Line(kSecret, "ops max_uploads=4x"), {"max_uploads", "unsigned integer"}},
      {Line(kSecret, "ops max_uploads="), {"max_uploads", "unsigned integer"}},
      {Line(kSecret, "ops max_sessions=1 max_sessions=2"), {"max_sessions is given twice"}},
      {Line("short-secret", "ops"), {"token is 12 characters", "at least 16"}},
      {Line(std::string(kMaxTokenLength + 1, 'x'), "ops"), {"longer than 256"}},
      {Line(std::string(kSecret) + "\xc3\xa9", "ops"), {"printable ASCII"}},
      {Line(std::string(kSecret) + "\x01", "ops"), {"printable ASCII"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.line);
    // A good line first, so the bad one is line 3 (after a comment), not line 1.
    const std::string text = Line(kOpsToken, "ops") + "# a comment\n" + c.line;
    absl::StatusOr<TokenTable> table = TokenTable::Parse(text, "tokens.txt");
    ASSERT_FALSE(table.ok());
    EXPECT_TRUE(IsError(table.status(), absl::StatusCode::kInvalidArgument, {"tokens.txt:3: "},
                        {kSecret, other_secret, "short-secret", kOpsToken, "xxxxxxxxxxxxxxxx"}));
    for (std::string_view needle : c.needles)
      EXPECT_TRUE(IsError(table.status(), absl::StatusCode::kInvalidArgument, {needle}));
  }
}

TEST(TokenTableTest, DuplicateTokenNamesTheEarlierLineNotTheToken) {
  const std::string text = Line(kSecret, "first") + "\n" + Line(kSecret, "second");
  absl::StatusOr<TokenTable> table = TokenTable::Parse(text, "tokens.txt");
  EXPECT_TRUE(IsError(table.status(), absl::StatusCode::kInvalidArgument,
                      {"tokens.txt:3: ", "duplicate token", "\"first\" on line 1"}, {kSecret}));
}

TEST(TokenTableTest, DuplicateName) {
  const std::string text = Line(kOpsToken, "ops") + Line(kSecret, "ops max_sessions=1");
  absl::StatusOr<TokenTable> table = TokenTable::Parse(text, "tokens.txt");
  EXPECT_TRUE(IsError(table.status(), absl::StatusCode::kInvalidArgument,
                      {"tokens.txt:2: ", "duplicate name \"ops\"", "line 1"},
                      {kSecret, kOpsToken}));
}

TEST(TokenTableTest, AFileWithoutTokensIsAnError) {
  for (std::string_view text : {"", "\n\n", "# only\n# comments\n", "  \t\r\n"}) {
    SCOPED_TRACE(std::string(text));
    EXPECT_TRUE(IsError(TokenTable::Parse(text, "tokens.txt").status(),
                        absl::StatusCode::kInvalidArgument, {"tokens.txt: ", "no tokens"}));
  }
}

// ---------------------------------------------------------------------------------------------
// TokenTable::Find and Load

TEST(TokenTableTest, FindMatchesOnlyTheWholeToken) {
  absl::StatusOr<TokenTable> table = TokenTable::Parse(ExampleFile(), "tokens.txt");
  ASSERT_TRUE(table.ok()) << table.status();
  const std::string ops = kOpsToken;
  ASSERT_NE(table->Find(ops), nullptr);
  EXPECT_EQ(table->Find(ops)->name, "ops");
  EXPECT_EQ(table->Find(ops.substr(0, ops.size() - 1)), nullptr);  // prefix
  EXPECT_EQ(table->Find(ops.substr(1)), nullptr);                  // suffix
  EXPECT_EQ(table->Find(ops + "x"), nullptr);                      // longer
  EXPECT_EQ(table->Find(ops + " "), nullptr);
  EXPECT_EQ(table->Find(std::string(ops.size(), 'a')), nullptr);   // same length
  EXPECT_EQ(table->Find("S3CR3T-OPS-TOKEN-0123456789"), nullptr);  // tokens are case-sensitive
  EXPECT_EQ(table->Find(""), nullptr);
  EXPECT_EQ(table->Find("ops"), nullptr);  // a name is not a token
}

TEST(TokenTableTest, LoadReadsAFileAndNamesItInErrors) {
  TempFile file;
  file.Write(ExampleFile());
  absl::StatusOr<TokenTable> table = TokenTable::Load(file.path());
  ASSERT_TRUE(table.ok()) << table.status();
  EXPECT_EQ(table->size(), 2u);

  file.Write(Line(kOpsToken, "ops") + Line(kSecret, "bad name=1"));
  EXPECT_TRUE(IsError(TokenTable::Load(file.path()).status(), absl::StatusCode::kInvalidArgument,
                      {file.path() + ":2: "}, {kSecret}));
}

TEST(TokenTableTest, LoadErrorsForMissingAndUnreadableFiles) {
  const std::string missing = ::testing::TempDir() + "/tessera_auth_test_no_such_file.txt";
  EXPECT_TRUE(IsError(TokenTable::Load(missing).status(), absl::StatusCode::kNotFound,
                      {"token file " + missing}));

  absl::StatusOr<TokenTable> dir = TokenTable::Load(::testing::TempDir());
  EXPECT_FALSE(dir.ok());
  EXPECT_NE(std::string(dir.status().message()).find("token file"), std::string::npos);

  if (geteuid() == 0) GTEST_SKIP() << "root reads files regardless of their mode";
  TempFile file;
  file.Write(ExampleFile());
  std::filesystem::permissions(file.path(), std::filesystem::perms::none);
  EXPECT_TRUE(IsError(TokenTable::Load(file.path()).status(), absl::StatusCode::kPermissionDenied,
                      {file.path()}));
}

// ---------------------------------------------------------------------------------------------
// Authenticator

TEST(AuthenticatorTest, OffEveryoneIsAnonymous) {
  Authenticator auth;
  EXPECT_FALSE(auth.enabled());
  EXPECT_EQ(auth.token_count(), 0u);
  EXPECT_TRUE(auth.Reload().ok());
  for (std::string_view header : {"", "Bearer whatever", "Basic abc"}) {
    absl::StatusOr<std::shared_ptr<const Principal>> p = auth.Authenticate(header);
    ASSERT_TRUE(p.ok()) << p.status();
    ASSERT_NE(*p, nullptr);
    EXPECT_EQ((*p)->name, "");
    EXPECT_EQ((*p)->max_sessions, std::nullopt);
    EXPECT_EQ((*p)->max_uploads, std::nullopt);
  }
}

TEST(AuthenticatorTest, FromFileErrors) {
  EXPECT_EQ(Authenticator::FromFile("").status().code(), absl::StatusCode::kInvalidArgument);
  const std::string missing = ::testing::TempDir() + "/tessera_auth_test_no_such_file.txt";
  EXPECT_TRUE(
      IsError(Authenticator::FromFile(missing).status(), absl::StatusCode::kNotFound, {missing}));
  TempFile file;
  file.Write("# nothing here\n");
  EXPECT_TRUE(IsError(Authenticator::FromFile(file.path()).status(),
                      absl::StatusCode::kInvalidArgument, {file.path(), "no tokens"}));
}

TEST(AuthenticatorTest, HeaderForms) {
  TempFile file;
  std::unique_ptr<Authenticator> auth = AuthFrom(file, ExampleFile());
  ASSERT_NE(auth, nullptr);
  EXPECT_TRUE(auth->enabled());
  EXPECT_EQ(auth->token_count(), 2u);

  for (const std::string& header : {Bearer(kOpsToken), "bearer " + std::string(kOpsToken),
                                    "BEARER " + std::string(kOpsToken)}) {
    SCOPED_TRACE(header);
    absl::StatusOr<std::shared_ptr<const Principal>> p = auth->Authenticate(header);
    ASSERT_TRUE(p.ok()) << p.status();
    EXPECT_EQ((*p)->name, "ops");
  }
  absl::StatusOr<std::shared_ptr<const Principal>> viewer =
      auth->Authenticate(Bearer(kViewerToken));
  ASSERT_TRUE(viewer.ok()) << viewer.status();
  EXPECT_EQ((*viewer)->max_sessions, 4u);

  EXPECT_TRUE(IsError(auth->Authenticate("").status(), absl::StatusCode::kUnauthenticated,
                      {"missing bearer token", "authorization: Bearer <token>"}));
  const std::string ops = kOpsToken;
  for (const std::string& header :
       {std::string("Bearer x"), "Basic " + ops, "Bearer  " + ops, "Bearer " + ops + " ",
        " Bearer " + ops, "Bearer\t" + ops, "Bearer" + ops, ops, std::string("Bearer"),
        std::string("Bearer "), Bearer(ops + "x"), Bearer(ops.substr(1))}) {
    SCOPED_TRACE(header);
    EXPECT_TRUE(IsError(auth->Authenticate(header).status(), absl::StatusCode::kUnauthenticated,
                        {"invalid bearer token"}, {ops}));
  }
}

TEST(AuthenticatorTest, ReloadSwapsTokensAndKeepsTheOldTableOnError) {
  TempFile file;
  std::unique_ptr<Authenticator> auth = AuthFrom(file, Line(kOpsToken, "ops"));
  ASSERT_NE(auth, nullptr);
  absl::StatusOr<std::shared_ptr<const Principal>> before = auth->Authenticate(Bearer(kOpsToken));
  ASSERT_TRUE(before.ok()) << before.status();

  file.Write(Line(kViewerToken, "viewer max_uploads=2") + Line(kSecret, "extra"));
  ASSERT_TRUE(auth->Reload().ok());
  EXPECT_EQ(auth->token_count(), 2u);
  EXPECT_EQ(auth->Authenticate(Bearer(kOpsToken)).status().code(),
            absl::StatusCode::kUnauthenticated);
  absl::StatusOr<std::shared_ptr<const Principal>> viewer =
      auth->Authenticate(Bearer(kViewerToken));
  ASSERT_TRUE(viewer.ok()) << viewer.status();
  EXPECT_EQ((*viewer)->name, "viewer");
  EXPECT_EQ((*viewer)->max_uploads, 2u);
  EXPECT_EQ((*before)->name, "ops");  // a principal outlives the table it came from

  file.Write(Line(kSecret, "ops") + "garbage\n");
  EXPECT_TRUE(IsError(auth->Reload(), absl::StatusCode::kInvalidArgument, {file.path() + ":2: "},
                      {kSecret}));
  EXPECT_EQ(auth->token_count(), 2u);
  EXPECT_TRUE(auth->Authenticate(Bearer(kViewerToken)).ok());
  EXPECT_FALSE(auth->Authenticate(Bearer(kOpsToken)).ok());

  ASSERT_EQ(std::remove(file.path().c_str()), 0);
  EXPECT_EQ(auth->Reload().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(auth->Authenticate(Bearer(kViewerToken)).ok());
}

// Readers authenticate while a writer flips the file between two tables. A token in both must
// always pass, one in neither must always fail, and the others may do either but must map to
// their own names.
TEST(AuthenticatorTest, ConcurrentAuthenticateAndReload) {
  constexpr char kAlways[] = "always-present-token-000001";
  constexpr char kOnlyA[] = "only-in-table-a-token-00002";
  constexpr char kOnlyB[] = "only-in-table-b-token-00003";
  const std::string table_a = Line(kAlways, "always") + Line(kOnlyA, "a");
  const std::string table_b = Line(kOnlyB, "b max_sessions=7") + Line(kAlways, "always");
  TempFile file;
  std::unique_ptr<Authenticator> auth = AuthFrom(file, table_a);
  ASSERT_NE(auth, nullptr);

  std::atomic<bool> done{false};
  std::atomic<int> wrong{0}, reload_errors{0};
  std::atomic<int64_t> ok_a{0}, ok_b{0};
  auto reader = [&] {
    std::shared_ptr<const Principal> held;  // kept across reloads
    while (!done.load()) {
      auto always = auth->Authenticate(Bearer(kAlways));
      if (!always.ok() || (*always)->name != "always") ++wrong;
      if (held != nullptr && held->name != "always") ++wrong;
      if (always.ok()) held = *always;
      auto a = auth->Authenticate(Bearer(kOnlyA));
      if (a.ok() ? (*a)->name != "a" : a.status().code() != absl::StatusCode::kUnauthenticated)
        ++wrong;
      ok_a += a.ok();
      auto b = auth->Authenticate("bearer " + std::string(kOnlyB));
      if (b.ok() ? (*b)->max_sessions != 7u
                 : b.status().code() != absl::StatusCode::kUnauthenticated)
        ++wrong;
      ok_b += b.ok();
      if (auth->Authenticate(Bearer(kSecret)).status().code() != absl::StatusCode::kUnauthenticated)
        ++wrong;
    }
  };
  std::vector<std::thread> readers;
  for (int i = 0; i < 4; ++i) readers.emplace_back(reader);
  for (int i = 0; i < 200; ++i) {
    file.Write(i % 2 == 0 ? table_b : table_a);
    if (!auth->Reload().ok()) ++reload_errors;
  }
  done = true;
  for (std::thread& t : readers) t.join();

  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(reload_errors.load(), 0);
  EXPECT_EQ(auth->token_count(), 2u);
  EXPECT_TRUE(auth->Authenticate(Bearer(kOnlyA)).ok());  // 200 flips end on table a
  EXPECT_FALSE(auth->Authenticate(Bearer(kOnlyB)).ok());
  // Not asserted: whether the readers happened to see both tables depends on scheduling.
  RecordProperty("ok_a", static_cast<int>(ok_a.load()));
  RecordProperty("ok_b", static_cast<int>(ok_b.load()));
}

// ---------------------------------------------------------------------------------------------
// UsageCounter

TEST(UsageCounterTest, LimitsPerName) {
  UsageCounter c;
  EXPECT_TRUE(c.TryAcquire("viewer", 2));
  EXPECT_TRUE(c.TryAcquire("viewer", 2));
  EXPECT_FALSE(c.TryAcquire("viewer", 2));  // at the limit: takes nothing
  EXPECT_EQ(c.count("viewer"), 2u);
  EXPECT_TRUE(c.TryAcquire("ops", 1));  // names are counted apart
  EXPECT_EQ(c.count("ops"), 1u);

  c.Release("viewer");
  EXPECT_EQ(c.count("viewer"), 1u);
  EXPECT_TRUE(c.TryAcquire("viewer", 2));
  EXPECT_FALSE(c.TryAcquire("viewer", 1));  // a lowered limit (after a reload) applies at once
  c.Release("viewer");
  c.Release("viewer");
  EXPECT_EQ(c.count("viewer"), 0u);
}

TEST(UsageCounterTest, ZeroUnlimitedAndUnbalancedRelease) {
  UsageCounter c;
  EXPECT_FALSE(c.TryAcquire("viewer", 0u));
  EXPECT_EQ(c.count("viewer"), 0u);
  for (int i = 0; i < 1000; ++i) ASSERT_TRUE(c.TryAcquire("ops", std::nullopt));
  EXPECT_EQ(c.count("ops"), 1000u);
  c.Release("nobody");  // ignored, no wrap-around
  EXPECT_EQ(c.count("nobody"), 0u);
  EXPECT_TRUE(c.TryAcquire("nobody", 1));
}

TEST(UsageCounterTest, ConcurrentAcquireNeverExceedsTheLimit) {
  constexpr uint32_t kLimit = 3;
  UsageCounter c;
  std::atomic<int> over{0};
  std::atomic<int> in_use{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 2000; ++i) {
        if (!c.TryAcquire("viewer", kLimit)) continue;
        if (++in_use > static_cast<int>(kLimit)) ++over;
        --in_use;
        c.Release("viewer");
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(over.load(), 0);
  EXPECT_EQ(c.count("viewer"), 0u);
}

}  // namespace
}  // namespace tessera::server
