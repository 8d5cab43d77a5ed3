#include "clients/cli/cli_common.h"
#include "clients/cli/json_float.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>

#include <grpcpp/support/client_interceptor.h>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "google/protobuf/descriptor.h"
#include "common/scene_id.h"

namespace tessera::cli {

namespace pb = google::protobuf;

// ---------------------------------------------------------------------------------------------
// Command line

ArgReader::ArgReader(const Invocation& inv) : inv_(inv) {}

bool ArgReader::Next() {
  if (next_ >= inv_.args.size()) return false;
  flag_ = inv_.args[next_++];
  has_inline_ = false;
  inline_value_.clear();
  // "--flag=value"; a positional word may contain '=' freely.
  if (absl::StartsWith(flag_, "--")) {
    const size_t eq = flag_.find('=');
    if (eq != std::string::npos) {
      inline_value_ = flag_.substr(eq + 1);
      flag_.resize(eq);
      has_inline_ = true;
    }
  }
  return true;
}

bool ArgReader::Is(absl::string_view name) const { return flag_ == name; }

bool ArgReader::IsPositional() const { return flag_ == "-" || !absl::StartsWith(flag_, "-"); }

std::string ArgReader::Value() {
  if (has_inline_) return inline_value_;
  if (next_ >= inv_.args.size()) Fail(absl::StrCat(flag_, " needs a value"));
  return inv_.args[next_++];
}

double ArgReader::Double() {
  const std::string v = Value();
  double d;
  if (!absl::SimpleAtod(v, &d) || !std::isfinite(d)) {
    Fail(absl::StrCat(flag_, ": not a number: '", v, "'"));
  }
  return d;
}

float ArgReader::Float() { return static_cast<float>(Double()); }

uint32_t ArgReader::Uint() {
  const std::string v = Value();
  uint32_t u;
  if (!absl::SimpleAtoi(v, &u))
    Fail(absl::StrCat(flag_, ": not a non-negative integer: '", v, "'"));
  return u;
}

void ArgReader::Fail(absl::string_view message) const {
  UsageError(inv_.command, absl::StrCat(message, " (see tessera ", inv_.command, " --help)"));
}

void ArgReader::Unknown() const {
  if (IsPositional()) Fail(absl::StrCat("unexpected argument '", flag_, "'"));
  Fail(absl::StrCat("unknown option '", flag_, "'"));
}

// ---------------------------------------------------------------------------------------------
// --json output and errors

namespace {

// What this run has written for --json. Process-wide, like stdout itself.
struct JsonOutput {
  bool on = false;
  bool printed = false;  // a document is on stdout
  Json first_error;      // ErrorJson of the first error reported; null before
};

JsonOutput& Output() {
  static JsonOutput output;
  return output;
}

void RememberError(absl::string_view code, absl::string_view message) {
  if (Output().first_error.is_null()) Output().first_error = ErrorJson(code, message);
}

}  // namespace

std::string ErrnoCodeName(int error_number) {
  return absl::StatusCodeToString(absl::ErrnoToStatusCode(error_number));
}

Json ErrorJson(absl::string_view code, absl::string_view message) {
  return {{"code", std::string(code)}, {"message", std::string(message)}};
}

Json ErrorJson(const grpc::Status& status) {
  return ErrorJson(StatusCodeName(status.error_code()), status.error_message());
}

Json FirstError() { return Output().first_error; }

void SetJsonOutput(bool json) { Output().on = json; }

int FinishOutput(int exit_code) {
  const JsonOutput& o = Output();
  if (o.on && !o.printed && exit_code != 0) {
    PrintJson({{"error", !o.first_error.is_null()
                             ? o.first_error
                             : ErrorJson("UNKNOWN", absl::StrCat("exit status ", exit_code))}});
  }
  return exit_code;
}

void UsageError(absl::string_view command, absl::string_view message) {
  RememberError("USAGE", message);
  if (Output().on && !Output().printed) PrintJson({{"error", Output().first_error}});
  if (command.empty()) {
    std::fprintf(stderr, "tessera: %.*s\n", int(message.size()), message.data());
  } else {
    std::fprintf(stderr, "tessera: %.*s: %.*s\n", int(command.size()), command.data(),
                 int(message.size()), message.data());
  }
  std::exit(kExitUsage);
}

// ---------------------------------------------------------------------------------------------
// Errors

absl::string_view StatusCodeName(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return "OK";
    case grpc::StatusCode::CANCELLED:
      return "CANCELLED";
    case grpc::StatusCode::UNKNOWN:
      return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT:
      return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND:
      return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS:
      return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED:
      return "PERMISSION_DENIED";
    case grpc::StatusCode::UNAUTHENTICATED:
      return "UNAUTHENTICATED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION:
      return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED:
      return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE:
      return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED:
      return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL:
      return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE:
      return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS:
      return "DATA_LOSS";
    default:
      return "UNKNOWN";
  }
}

int ReportRpcError(const Invocation& inv, const grpc::Status& status) {
  std::string message = status.error_message();
  // Transport failures do not say where they were going; the user needs to know.
  if (status.error_code() == grpc::StatusCode::UNAVAILABLE ||
      status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED) {
    absl::StrAppend(&message, " (server ", inv.global.server, ")");
  }
  std::fprintf(stderr, "tessera: %s: %s: %s\n", inv.command.c_str(),
               std::string(StatusCodeName(status.error_code())).c_str(), message.c_str());
  RememberError(StatusCodeName(status.error_code()), message);
  return kExitError;
}

int ReportError(const Invocation& inv, absl::string_view message, absl::string_view code) {
  std::fprintf(stderr, "tessera: %s: %.*s\n", inv.command.c_str(), int(message.size()),
               message.data());
  RememberError(code, message);
  return kExitError;
}

int ReportError(const Invocation& inv, const absl::Status& status) {
  return ReportError(inv, status.message(), absl::StatusCodeToString(status.code()));
}

// ---------------------------------------------------------------------------------------------
// Connection

namespace {

absl::StatusOr<std::string> ReadFile(const std::string& path, const char* flag) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat(flag, ": cannot read '", path, "'"));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Adds "authorization: Bearer <token>" to every call of the channel. An interceptor rather
// than call credentials, because gRPC sends call credentials only over TLS, and a token to a
// daemon on loopback without TLS is a normal set-up.
class BearerInterceptor final : public grpc::experimental::Interceptor {
 public:
  explicit BearerInterceptor(const std::string* header) : header_(header) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA))
      methods->GetSendInitialMetadata()->insert({"authorization", *header_});
    methods->Proceed();
  }

 private:
  const std::string* header_;
};

class BearerInterceptorFactory final
    : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit BearerInterceptorFactory(std::string token) : header_("Bearer " + token) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(
      grpc::experimental::ClientRpcInfo*) override {
    return new BearerInterceptor(&header_);
  }

 private:
  const std::string header_;  // lives as long as the channel (which owns the factory)
};

}  // namespace

absl::StatusOr<std::string> ReadTokenFile(const std::string& path) {
  absl::StatusOr<std::string> text = ReadFile(path, "--token-file");
  if (!text.ok()) return text.status();
  std::string token(absl::StripAsciiWhitespace(text->substr(0, text->find('\n'))));
  if (token.empty())
    return absl::InvalidArgumentError(absl::StrCat("--token-file: '", path, "' has no token"));
  return token;
}

std::shared_ptr<grpc::Channel> MakeChannel(const Invocation& inv, const std::string& target,
                                           bool round_robin, const std::string& tls_name) {
  grpc::ChannelArguments args;
  // Frames can be far larger than gRPC's 4 MiB default (a 4K PNG is ~30 MB).
  args.SetMaxReceiveMessageSize(-1);
  // A server lost without a reset (a node gone, a partition) ends the calls within ~15 s
  // instead of the TCP timeout's minutes; tesserad accepts a ping every 10 s.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, 10000);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 5000);
  // A replica dialled by address is checked against the name it was found under.
  if (inv.global.tls && !tls_name.empty()) args.SetSslTargetNameOverride(tls_name);
  if (round_robin) {
    args.SetLoadBalancingPolicyName("round_robin");
    // A daemon that comes back (or starts late) is reconnected within ~2 s, not gRPC's default
    // of up to 2 minutes.
    args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 500);
    args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  }
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (inv.global.tls) {
    grpc::SslCredentialsOptions ssl;
    for (auto [path, flag, out] :
         {std::tuple{&inv.global.tls_ca_file, "--tls-ca", &ssl.pem_root_certs},
          std::tuple{&inv.global.tls_cert_file, "--tls-cert", &ssl.pem_cert_chain},
          std::tuple{&inv.global.tls_key_file, "--tls-key", &ssl.pem_private_key}}) {
      if (path->empty()) continue;
      absl::StatusOr<std::string> pem = ReadFile(*path, flag);
      if (!pem.ok()) {
        ReportError(inv, pem.status());
        return nullptr;
      }
      *out = *std::move(pem);
    }
    credentials = grpc::SslCredentials(ssl);
  }
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> hooks;
  if (!inv.global.token.empty())
    hooks.push_back(std::make_unique<BearerInterceptorFactory>(inv.global.token));
  return grpc::experimental::CreateCustomChannelWithInterceptors(target, credentials, args,
                                                                 std::move(hooks));
}

absl::StatusOr<std::shared_ptr<grpc::Channel>> TryConnect(const Invocation& inv) {
  std::shared_ptr<grpc::Channel> channel = MakeChannel(inv, inv.global.server, false);
  if (!channel) return absl::InvalidArgumentError("the TLS options could not be read");
  const auto deadline = std::chrono::system_clock::now() +
                        std::chrono::duration_cast<std::chrono::system_clock::duration>(
                            std::chrono::duration<double>(inv.global.connect_timeout_s));
  grpc_connectivity_state state = channel->GetState(/*try_to_connect=*/true);
  while (state != GRPC_CHANNEL_READY) {
    // A refused connection or an unresolvable name shows up as TRANSIENT_FAILURE at once;
    // gRPC would keep retrying with backoff, but the user wants to hear about it now.
    if (state == GRPC_CHANNEL_TRANSIENT_FAILURE || state == GRPC_CHANNEL_SHUTDOWN) {
      return absl::UnavailableError(
          absl::StrCat("cannot connect to tesserad at ", inv.global.server,
                       ": connection failed (is tesserad running there? set the "
                       "address with --server or $TESSERA_SERVER",
                       inv.global.tls ? "; does it speak TLS with a certificate "
                                        "your --tls-ca trusts?"
                                      : "; does it need --tls?",
                       ")"));
    }
    if (!channel->WaitForStateChange(state, deadline)) {
      return absl::DeadlineExceededError(
          absl::StrFormat("cannot connect to tesserad at %s: no answer within %g s",
                          inv.global.server, inv.global.connect_timeout_s));
    }
    state = channel->GetState(/*try_to_connect=*/true);
  }
  return channel;
}

std::shared_ptr<grpc::Channel> Connect(const Invocation& inv) {
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = TryConnect(inv);
  if (channel.ok()) return *channel;
  // MakeChannel has said why when the TLS files could not be read.
  if (!absl::IsInvalidArgument(channel.status())) ReportError(inv, channel.status());
  return nullptr;
}

std::unique_ptr<v1::RenderService::Stub> ConnectStub(const Invocation& inv) {
  std::shared_ptr<grpc::Channel> channel = Connect(inv);
  if (!channel) return nullptr;
  return v1::RenderService::NewStub(channel);
}

void SetDeadline(grpc::ClientContext* context, double seconds) {
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::duration_cast<std::chrono::system_clock::duration>(
                            std::chrono::duration<double>(seconds)));
}

grpc::Status ResolveSceneId(v1::RenderService::Stub* stub, const std::string& id,
                            std::string* resolved, v1::SceneInfo* info, bool* found) {
  *resolved = id;
  if (found) *found = false;
  if (id == "demo" || IsSha256Hex(id)) {
    if (!info && !found) return grpc::Status::OK;
    grpc::ClientContext context;
    SetDeadline(&context, kShortCallSeconds);
    v1::HasSceneRequest request;
    request.set_scene_id(id);
    v1::HasSceneResponse response;
    grpc::Status status = stub->HasScene(&context, request, &response);
    if (!status.ok()) return status;
    if (found) *found = response.present();
    if (info && response.present()) *info = response.info();
    return grpc::Status::OK;
  }
  // Shorter prefixes are too easy to get wrong (and RenderRequest takes 8+ too): the server's
  // NOT_FOUND names them.
  if (id.size() < kMinSceneIdPrefix) return grpc::Status::OK;
  // A prefix: only ListScenes knows which ids exist.
  grpc::ClientContext context;
  SetDeadline(&context, kShortCallSeconds);
  v1::ListScenesResponse list;
  grpc::Status status = stub->ListScenes(&context, v1::ListScenesRequest(), &list);
  if (!status.ok()) return status;
  std::vector<const v1::SceneInfo*> matches;
  for (const v1::SceneInfo& scene : list.scenes()) {
    if (!scene.deleted() && absl::StartsWith(scene.scene_id(), id)) matches.push_back(&scene);
  }
  if (matches.size() > 1) {
    std::vector<std::string> names;
    for (const v1::SceneInfo* m : matches) names.push_back(m->scene_id().substr(0, 12));
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        absl::StrCat("scene id '", id, "' matches ", matches.size(), " scenes (",
                                     absl::StrJoin(names, ", "), "); give more characters"));
  }
  if (matches.size() == 1) {
    *resolved = matches[0]->scene_id();
    if (found) *found = true;
    if (info) *info = *matches[0];
  }
  return grpc::Status::OK;
}

// ---------------------------------------------------------------------------------------------
// Output

bool StdoutIsTty() { return isatty(STDOUT_FILENO) == 1; }
bool StderrIsTty() { return isatty(STDERR_FILENO) == 1; }

void PrintJson(const Json& j) {
  Output().printed = true;
  const std::string text = j.dump(2);
  std::fwrite(text.data(), 1, text.size(), stdout);
  std::fputc('\n', stdout);
}

std::string EnumShortName(const pb::EnumValueDescriptor* value) {
  if (value->number() == 0) return "unspecified";
  const std::string& name = value->name();
  // The words every named value of the type starts with (AA_, JOB_OUTPUT_), at least the first.
  size_t prefix = name.find('_') == std::string::npos ? 0 : name.find('_') + 1;
  for (size_t end = name.find('_', prefix); end != std::string::npos;
       end = name.find('_', end + 1)) {
    const std::string longer = name.substr(0, end + 1);
    bool shared = true;
    for (int i = 0; i < value->type()->value_count() && shared; ++i) {
      const pb::EnumValueDescriptor* v = value->type()->value(i);
      shared = v->number() == 0 || (v->name().rfind(longer, 0) == 0 && v->name() != longer);
    }
    if (!shared) break;
    prefix = end + 1;
  }
  return absl::AsciiStrToLower(name.substr(prefix));
}

int ParseEnumShortName(const pb::EnumDescriptor* type, absl::string_view name) {
  for (int i = 0; i < type->value_count(); ++i) {
    const pb::EnumValueDescriptor* v = type->value(i);
    if (v->number() != 0 && EnumShortName(v) == name) return v->number();
  }
  return -1;
}

namespace {

Json FieldValue(const pb::Message& msg, const pb::FieldDescriptor* f, int index) {
  const pb::Reflection* r = msg.GetReflection();
  const bool rep = f->is_repeated();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_INT32:
      return rep ? r->GetRepeatedInt32(msg, f, index) : r->GetInt32(msg, f);
    case pb::FieldDescriptor::CPPTYPE_INT64:
      return rep ? r->GetRepeatedInt64(msg, f, index) : r->GetInt64(msg, f);
    case pb::FieldDescriptor::CPPTYPE_UINT32:
      return rep ? r->GetRepeatedUInt32(msg, f, index) : r->GetUInt32(msg, f);
    case pb::FieldDescriptor::CPPTYPE_UINT64:
      return rep ? r->GetRepeatedUInt64(msg, f, index) : r->GetUInt64(msg, f);
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
      return rep ? r->GetRepeatedDouble(msg, f, index) : r->GetDouble(msg, f);
    case pb::FieldDescriptor::CPPTYPE_FLOAT:
      return FloatForJson(rep ? r->GetRepeatedFloat(msg, f, index) : r->GetFloat(msg, f));
    case pb::FieldDescriptor::CPPTYPE_BOOL:
      return rep ? r->GetRepeatedBool(msg, f, index) : r->GetBool(msg, f);
    case pb::FieldDescriptor::CPPTYPE_ENUM:
      return EnumShortName(rep ? r->GetRepeatedEnum(msg, f, index) : r->GetEnum(msg, f));
    case pb::FieldDescriptor::CPPTYPE_STRING:
      return rep ? r->GetRepeatedString(msg, f, index) : r->GetString(msg, f);
    case pb::FieldDescriptor::CPPTYPE_MESSAGE:
      return ToJson(rep ? r->GetRepeatedMessage(msg, f, index) : r->GetMessage(msg, f));
  }
  return nullptr;
}

}  // namespace

Json ToJson(const pb::Message& msg) {
  Json j = Json::object();
  const pb::Descriptor* d = msg.GetDescriptor();
  const pb::Reflection* r = msg.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->type() == pb::FieldDescriptor::TYPE_BYTES) continue;
    if (f->is_repeated()) {
      Json arr = Json::array();
      for (int k = 0; k < r->FieldSize(msg, f); ++k) arr.push_back(FieldValue(msg, f, k));
      j[f->name()] = std::move(arr);
    } else if (!f->has_presence() || r->HasField(msg, f)) {
      // Fields with presence (messages, `optional`, oneof members) only when set, so "unset"
      // stays distinguishable from a zero value.
      j[f->name()] = FieldValue(msg, f, -1);
    }
  }
  return j;
}

std::string HumanBytes(uint64_t bytes) {
  if (bytes < 1024) return absl::StrCat(bytes, " B");
  const double kib = bytes / 1024.0;
  if (kib < 1024) return absl::StrFormat("%.1f KiB", kib);
  const double mib = kib / 1024.0;
  if (mib < 1024) return absl::StrFormat("%.1f MiB", mib);
  return absl::StrFormat("%.2f GiB", mib / 1024.0);
}

std::string HumanDuration(double seconds) {
  if (seconds < 60) return absl::StrFormat("%.1f s", seconds);
  const uint64_t s = static_cast<uint64_t>(seconds);
  if (s < 3600) return absl::StrFormat("%um %02us", s / 60, s % 60);
  if (s < 86400) return absl::StrFormat("%uh %02um", s / 3600, s / 60 % 60);
  return absl::StrFormat("%ud %02uh", s / 86400, s / 3600 % 24);
}

double Median(std::vector<double> v) { return Percentile(std::move(v), 50); }

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  // Nearest rank: the smallest value with at least p% of the samples at or below it.
  const size_t rank = static_cast<size_t>(std::ceil(p / 100.0 * v.size()));
  return v[std::clamp<size_t>(rank, 1, v.size()) - 1];
}

// The addresses behind --servers: "a:1,b:2" (names resolved here) or "dns:///name:port".
// `lb_target` is what the round_robin channel dials; `addresses` each daemon (for uploads).
absl::Status ResolveServers(const std::string& servers, std::string* lb_target,
                            std::vector<std::string>* addresses,
                            std::map<std::string, std::string>* host_of) {
  std::vector<std::string> parts;
  std::string dns_port;
  if (servers.rfind("dns:", 0) == 0) {
    // dns:///host:port (or dns://authority/host:port): gRPC resolves and re-resolves it; the
    // addresses are resolved here too, for the uploads.
    *lb_target = servers;
    std::string hostport = servers.substr(servers.find('/', 6) == std::string::npos
                                              ? 4
                                              : servers.find('/', 6) + 1);
    parts.push_back(hostport);
  } else {
    for (absl::string_view p : absl::StrSplit(servers, ',', absl::SkipEmpty()))
      parts.emplace_back(p);
  }
  if (parts.empty()) return absl::InvalidArgumentError("--servers: no address");
  std::vector<std::string> v4, v6;
  for (const std::string& p : parts) {
    const size_t colon = p.rfind(':');
    if (colon == std::string::npos || colon == 0)
      return absl::InvalidArgumentError(absl::StrCat("--servers: '", p, "' is not HOST:PORT"));
    std::string host = p.substr(0, colon);
    const std::string port = p.substr(colon + 1);
    if (host.size() > 2 && host.front() == '[' && host.back() == ']')
      host = host.substr(1, host.size() - 2);
    addrinfo hints{};
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* res = nullptr;
    if (int rc = getaddrinfo(host.c_str(), port.c_str(), &hints, &res); rc != 0)
      return absl::UnavailableError(
          absl::StrCat("--servers: cannot resolve '", host, "': ", gai_strerror(rc)));
    for (addrinfo* a = res; a; a = a->ai_next) {
      char buf[INET6_ADDRSTRLEN] = {};
      if (a->ai_family == AF_INET) {
        inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(a->ai_addr)->sin_addr, buf,
                  sizeof buf);
        const std::string addr = absl::StrCat(buf, ":", port);
        if (std::find(v4.begin(), v4.end(), addr) == v4.end()) v4.push_back(addr);
        if (host_of) host_of->emplace(addr, host);
      } else if (a->ai_family == AF_INET6) {
        inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(a->ai_addr)->sin6_addr, buf,
                  sizeof buf);
        const std::string addr = absl::StrCat("[", buf, "]:", port);
        if (std::find(v6.begin(), v6.end(), addr) == v6.end()) v6.push_back(addr);
        if (host_of) host_of->emplace(addr, host);
      }
    }
    freeaddrinfo(res);
  }
  // One family for the static list (gRPC's ipv4:/ipv6: schemes); IPv4 when there is any.
  *addresses = !v4.empty() ? v4 : v6;
  if (addresses->empty()) return absl::UnavailableError("--servers: no address resolved");
  if (lb_target->empty())
    *lb_target = absl::StrCat(!v4.empty() ? "ipv4:" : "ipv6:", absl::StrJoin(*addresses, ","));
  return absl::OkStatus();
}


}  // namespace tessera::cli
