#pragma once
// The renderer's logger. It writes to stderr, so tools that print results on stdout (JSON for
// scripts) stay parseable.
#include <spdlog/spdlog.h>

namespace tessera {
spdlog::logger& Log();
}  // namespace tessera
