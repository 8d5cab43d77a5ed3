#include "renderer/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>

namespace tessera {

spdlog::logger& Log() {
  static std::shared_ptr<spdlog::logger> logger = [] {
    std::shared_ptr<spdlog::logger> l = spdlog::get("tessera");
    return l ? l : spdlog::stderr_color_mt("tessera");
  }();
  return *logger;
}

}  // namespace tessera
