#pragma once
// Shared pieces of the `tessera` client: command-line reading, the connection to tesserad,
// error reporting, and turning messages into JSON or human-readable text.
#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "google/protobuf/message.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::cli {

// JSON output keeps the order fields are added in (proto field order), not alphabetical.
using Json = nlohmann::ordered_json;

// Exit codes (the table is in tessera --help and the README): 0 done; 1 the server (or the
// local machine) failed the command; 2 a command line that could not be understood (nothing
// was sent); 3 the work ran but did not succeed (a job that ended failed or cancelled); 130
// interrupted by Ctrl-C (128 + SIGINT, what a shell reports for a killed command).
inline constexpr int kExitError = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitJobFailed = 3;
inline constexpr int kExitInterrupted = 130;

// Flags valid before or after the command name.
struct GlobalOptions {
  std::string server = "127.0.0.1:50051";
  bool json = false;
  double connect_timeout_s = 10;
  std::string token;  // bearer token sent with every call ("" = none)
  bool tls = false;
  std::string tls_ca_file;    // trusted CA (PEM); empty: the system's roots
  std::string tls_cert_file;  // client certificate for mTLS (PEM)
  std::string tls_key_file;
};

// The first line of a token file, trimmed; INVALID_ARGUMENT naming the file when empty.
absl::StatusOr<std::string> ReadTokenFile(const std::string& path);

// What every command gets: the global options and the words after the command name, with the
// global flags taken out.
struct Invocation {
  GlobalOptions global;
  std::string command;
  std::vector<std::string> args;
};

// Walks one command's arguments. Accepts "--flag value" and "--flag=value".
class ArgReader {
 public:
  explicit ArgReader(const Invocation& inv);

  // Moves to the next argument; false at the end.
  bool Next();
  // The current argument is the flag `name` (with or without an "=value" part).
  bool Is(absl::string_view name) const;
  // A word that does not start with '-' (or "-" alone).
  bool IsPositional() const;
  const std::string& current() const { return flag_; }
  // The current flag's value: its "=value" part, else the next argument.
  std::string Value();
  double Double();
  float Float();
  uint32_t Uint();

  [[noreturn]] void Fail(absl::string_view message) const;
  [[noreturn]] void Unknown() const;

 private:
  const Invocation& inv_;
  size_t next_ = 0;
  std::string flag_;
  bool has_inline_ = false;
  std::string inline_value_;
};

// "tessera: COMMAND: MESSAGE" on stderr (with --json, the error document on stdout), then
// exit(kExitUsage).
[[noreturn]] void UsageError(absl::string_view command, absl::string_view message);

// Errors go to stderr as one human-readable line, and are remembered for --json (see
// FinishOutput): the first one reported becomes the error document of a command that prints
// none of its own.
//
// "tessera: COMMAND: CODE_NAME: message" on stderr; returns kExitError so callers can
// `return ReportRpcError(...)`.
int ReportRpcError(const Invocation& inv, const grpc::Status& status);
// "tessera: COMMAND: message" on stderr; returns kExitError. `code` is the error's name in
// --json output: a gRPC status code name (UNAVAILABLE, NOT_FOUND, ...).
int ReportError(const Invocation& inv, absl::string_view message,
                absl::string_view code = "UNKNOWN");
// The same with the status's message and code.
int ReportError(const Invocation& inv, const absl::Status& status);

// The status code name of a failed system call's errno ("NOT_FOUND" for ENOENT, ...).
std::string ErrnoCodeName(int error_number);

// {"code": "NOT_FOUND", "message": "..."}: how --json output names an error.
Json ErrorJson(absl::string_view code, absl::string_view message);
Json ErrorJson(const grpc::Status& status);
// The first error reported so far (ErrorJson), or null.
Json FirstError();

// --json output: exactly one JSON document on stdout per run, whatever happens. main() turns
// it on before parsing the command line (so usage errors are documents too) and passes the
// command's exit code through FinishOutput, which prints {"error": FirstError()} when the
// command failed without printing a document of its own.
void SetJsonOutput(bool json);
int FinishOutput(int exit_code);

absl::string_view StatusCodeName(grpc::StatusCode code);

// A channel to inv.global.server that is READY, or nullptr after printing why not (the address
// and whether it refused or did not answer in time).
std::shared_ptr<grpc::Channel> Connect(const Invocation& inv);
// The same without printing: UNAVAILABLE (refused, unresolvable) or DEADLINE_EXCEEDED (no answer
// within --connect-timeout) naming the address; INVALID_ARGUMENT when a TLS file could not be
// read (MakeChannel printed why).
absl::StatusOr<std::shared_ptr<grpc::Channel>> TryConnect(const Invocation& inv);
// A channel to `target` with the global TLS and token options, not waited for (nullptr after
// printing why when a TLS file cannot be read). round_robin: gRPC's client-side load
// balancing over every address the target resolves to (an "ipv4:a,b" list or a dns:/// name).
// `tls_name`: the name a TLS server's certificate is checked against, when `target` is an
// address found under that name (a replica of --servers).
std::shared_ptr<grpc::Channel> MakeChannel(const Invocation& inv, const std::string& target,
                                           bool round_robin, const std::string& tls_name = "");
std::unique_ptr<v1::RenderService::Stub> ConnectStub(const Invocation& inv);

// The addresses behind --servers: "a:1,b:2" (names resolved here) or "dns:///name:port" (every
// address the name resolves to: a headless Service's replicas). `lb_target` is what a
// round_robin channel dials; `addresses` each daemon, and `host_of` (when given) the name each
// was resolved from (for TLS). INVALID_ARGUMENT / UNAVAILABLE naming --servers.
absl::Status ResolveServers(const std::string& servers, std::string* lb_target,
                            std::vector<std::string>* addresses,
                            std::map<std::string, std::string>* host_of = nullptr);

// A deadline `seconds` from now on `context`.
void SetDeadline(grpc::ClientContext* context, double seconds);
// Deadline of the small unary calls (info, list, has, delete).
inline constexpr double kShortCallSeconds = 30;

// Resolves a scene id the way people type it: "demo", a full id, or a unique prefix of 8+
// characters of the ids ListScenes shows (e.g. the 12 of `tessera scenes`). Unknown ids are
// returned unchanged so the server's NOT_FOUND names them. On an RPC error, returns it.
inline constexpr size_t kMinSceneIdPrefix = 8;
grpc::Status ResolveSceneId(v1::RenderService::Stub* stub, const std::string& id,
                            std::string* resolved, v1::SceneInfo* info = nullptr,
                            bool* found = nullptr);

// Output helpers.
bool StdoutIsTty();
bool StderrIsTty();
// Prints `j` as the one JSON document on stdout (at most once per run; see SetJsonOutput).
void PrintJson(const Json& j);

// Every field of `msg` as JSON with proto field names: numbers as numbers (also 64-bit ones),
// enums as their lower-case setting names ("msaa"), bytes fields left out (callers give sizes).
Json ToJson(const google::protobuf::Message& msg);

// Lower-case name of an enum value without the prefix all of its type's values share: AA_MSAA
// -> "msaa", CULLING_GPU_FRUSTUM -> "gpu_frustum", DEBUG_LIGHT_HEATMAP -> "light_heatmap",
// JOB_OUTPUT_SERVER_DIR -> "server_dir". These are
// the names renderer/settings.h uses (ParseAaMode, ToString) and SettingChoices lists.
std::string EnumShortName(const google::protobuf::EnumValueDescriptor* value);
// The value of `type` whose short name is `name`, or -1. Value 0 (UNSPECIFIED) never matches.
int ParseEnumShortName(const google::protobuf::EnumDescriptor* type, absl::string_view name);

// "1.5 MiB", "312 KiB", "17 B".
std::string HumanBytes(uint64_t bytes);
// "3h 12m", "4m 05s", "12.3 s".
std::string HumanDuration(double seconds);

// Median and 95th percentile (nearest rank) of `v`; 0 when empty.
double Median(std::vector<double> v);
double Percentile(std::vector<double> v, double p);

}  // namespace tessera::cli
