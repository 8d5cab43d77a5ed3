#pragma once
// The subcommands of `tessera`. Each parses its own arguments (exiting with kExitUsage on a bad
// command line), talks to the server and returns the process exit code.
#include "clients/cli/cli_common.h"

namespace tessera::cli {

struct Command {
  const char* name;
  const char* summary;  // one line for `tessera --help`
  const char* usage;    // `tessera NAME --help`
  bool render_flags;    // takes the camera and settings flags (their usage follows `usage`)
  int (*run)(const Invocation& inv);
};

extern const Command kInfoCommand;
extern const Command kUploadCommand;
extern const Command kScenesCommand;
extern const Command kRmCommand;
extern const Command kRenderCommand;
extern const Command kStreamCommand;
extern const Command kJobCommand;
extern const Command kBenchCommand;

// Uploads the glTF file set at `path` unless the server has it (progress on stderr, errors
// reported); its scene id in `scene_id`. False on error.
bool UploadSceneFile(const Invocation& inv, v1::RenderService::Stub* stub,
                     const std::string& path, std::string* scene_id);

}  // namespace tessera::cli
