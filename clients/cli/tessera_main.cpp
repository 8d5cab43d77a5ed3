// tessera: the command-line client of tesserad. `tessera COMMAND ...` with the subcommands in
// cli_commands.h; this file only reads the global flags, picks the command and prints usage.
#include <grpc/support/log.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/string_view.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_render_flags.h"

namespace tessera::cli {
namespace {

constexpr const Command* kCommands[] = {&kInfoCommand, &kUploadCommand, &kScenesCommand,
                                        &kRmCommand,   &kRenderCommand, &kStreamCommand,
                                        &kJobCommand,  &kBenchCommand};

constexpr char kGlobalUsage[] = R"(global flags (anywhere on the line):
  --server ADDR       tesserad's address (default: $TESSERA_SERVER, else 127.0.0.1:50051)
  --json              machine-readable output: exactly one JSON document on stdout, also on
                      failure: {"error": {"code": "NOT_FOUND", "message": "..."}} (code: the
                      gRPC status name, or USAGE for a bad command line); progress and errors
                      go to stderr
  --connect-timeout SEC   give up connecting after SEC seconds (default 10)
  --token-file FILE   send the bearer token in FILE (first line) with every call; the
                      token can also come from $TESSERA_TOKEN
  --tls               connect with TLS, trusting the system's CA certificates
  --tls-ca FILE       connect with TLS, trusting the CA certificate(s) in FILE (implies --tls)
  --tls-cert FILE --tls-key FILE   client certificate and key for servers that require mTLS
  -h, --help          this text; `tessera COMMAND --help` for one command

exit status:
  0    done
  1    the server (or the local system) failed the command; bench: a configuration failed
  2    a bad command line (nothing was sent)
  3    job submit / job watch: the job ended failed or cancelled
  130  interrupted (Ctrl-C) in stream or bench, after printing what was measured
Errors print the gRPC status code and message on stderr, e.g.
  tessera: render: NOT_FOUND: scene_id: no scene "abc"
)";

void PrintMainUsage(FILE* out) {
  std::fprintf(out,
               "usage: tessera [--server ADDR] [--json] COMMAND [options]\n"
               "The command-line client of tesserad, the Tessera render server.\n\ncommands:\n");
  for (const Command* c : kCommands) std::fprintf(out, "  %-8s %s\n", c->name, c->summary);
  std::fprintf(out, "\n%s", kGlobalUsage);
}

void PrintCommandUsage(const Command& c) {
  std::fputs(c.usage, stdout);
  if (c.render_flags) std::printf("\n%s\n%s", kCameraFlagsUsage, SettingsFlagsUsageText().c_str());
  std::printf("\n%s", kGlobalUsage);
}

const Command* FindCommand(absl::string_view name) {
  for (const Command* c : kCommands) {
    if (name == c->name) return c;
  }
  return nullptr;
}

// Takes the global flags out of argv wherever they are; the first other word names the
// command, and everything else belongs to it.
struct ParsedLine {
  Invocation inv;
  const Command* command = nullptr;
  bool help = false;
};

ParsedLine ParseLine(int argc, char** argv) {
  ParsedLine line;
  GlobalOptions& g = line.inv.global;
  // --json anywhere on the line applies to errors found before it is reached, too.
  for (int i = 1; i < argc; ++i) {
    if (absl::string_view(argv[i]) == "--json") SetJsonOutput(true);
  }
  if (const char* env = std::getenv("TESSERA_SERVER"); env && *env) g.server = env;
  if (const char* env = std::getenv("TESSERA_TOKEN"); env && *env)
    g.token = std::string(absl::StripAsciiWhitespace(env));
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](absl::string_view flag) -> std::string {
      const std::string prefix = absl::StrCat(flag, "=");
      if (arg.rfind(prefix, 0) == 0) return arg.substr(prefix.size());
      if (i + 1 >= argc) UsageError(line.inv.command, absl::StrCat(flag, " needs a value"));
      return argv[++i];
    };
    const auto is = [&](absl::string_view flag) {
      return arg == flag || arg.rfind(absl::StrCat(flag, "="), 0) == 0;
    };
    if (is("--server")) {
      g.server = value("--server");
      if (g.server.empty()) UsageError(line.inv.command, "--server needs an address");
    } else if (arg == "--json") {
      g.json = true;
    } else if (is("--connect-timeout")) {
      const std::string v = value("--connect-timeout");
      if (!absl::SimpleAtod(v, &g.connect_timeout_s) || !(g.connect_timeout_s > 0)) {
        UsageError(line.inv.command,
                   absl::StrCat("--connect-timeout: not a positive number: '", v, "'"));
      }
    } else if (is("--token-file")) {
      const std::string path = value("--token-file");
      absl::StatusOr<std::string> token = ReadTokenFile(path);
      if (!token.ok()) UsageError(line.inv.command, token.status().message());
      g.token = *token;
    } else if (arg == "--tls") {
      g.tls = true;
    } else if (is("--tls-ca")) {
      g.tls_ca_file = value("--tls-ca");
      g.tls = true;
    } else if (is("--tls-cert")) {
      g.tls_cert_file = value("--tls-cert");
    } else if (is("--tls-key")) {
      g.tls_key_file = value("--tls-key");
    } else if (arg == "--help" || arg == "-h") {
      line.help = true;
    } else if (line.command == nullptr && arg == "help") {
      line.help = true;  // `tessera help [COMMAND]`
    } else if (line.command == nullptr) {
      if (!arg.empty() && arg[0] == '-') {
        UsageError(
            "", absl::StrCat("unknown option '", arg, "' before the command (see tessera --help)"));
      }
      line.command = FindCommand(arg);
      if (line.command == nullptr) {
        UsageError("", absl::StrCat("unknown command '", arg, "' (see tessera --help)"));
      }
      line.inv.command = arg;
    } else {
      line.inv.args.push_back(arg);
    }
  }
  if (g.tls_cert_file.empty() != g.tls_key_file.empty())
    UsageError(line.inv.command, "--tls-cert and --tls-key go together");
  if (!g.tls_cert_file.empty()) g.tls = true;
  return line;
}

}  // namespace
}  // namespace tessera::cli

int main(int argc, char** argv) {
  using namespace tessera::cli;
  // gRPC's own log lines ("ssl_transport_security.cc:1501] Handshake failed ...") would come
  // before the CLI's message, which already says what failed and what to check.
  // GRPC_VERBOSITY=debug (or any value) brings them back.
  if (std::getenv("GRPC_VERBOSITY") == nullptr) gpr_set_log_function([](gpr_log_func_args*) {});
  const ParsedLine line = ParseLine(argc, argv);
  if (line.help) {
    if (line.command) {
      PrintCommandUsage(*line.command);
    } else {
      PrintMainUsage(stdout);
    }
    return 0;
  }
  if (line.command == nullptr) {
    PrintMainUsage(stderr);  // a usage error: nothing on stdout but the --json error
    UsageError("", "which command? (see tessera --help)");
  }
  return FinishOutput(line.command->run(line.inv));
}
